//! The tissue's condensed stiffness and damping at one tool's contact: the `K` and `D` of the local model.
//!
//! Owns: [`ContactStiffness`], a small static solve around the nodes a tool holds, run a few iterations per
//! tick so it never spikes a tick, and its latest result.
//!
//! How `K` is derived. When the tool moves by `dx`, each held node `i` slides along its push direction `d_i`
//! (minus its rest normal) just enough to stay on the tool surface (tool normal `n_i` there): it moves by
//! `u_i = d_i (n_i . dx) / (n_i . d_i)`; the contact is frictionless, so this is the only motion the tool
//! imposes. Only the motion along the contact normal `n` (the direction of the tool force) is solved, and
//! `K = k_n n n^T`: a frictionless tool sliding over homogeneous tissue drags its dent along at no cost in
//! energy (the field is translation invariant), so the tangential stiffness is zero. (A three-direction solve
//! was built and measured first: with the held set fixed it gave the pad a tangential stiffness of 2.7 N/mm,
//! an artefact of freezing which nodes are held, that made a stroke feel sticky at a distance.) The rest of
//! the tissue then relaxes: the free nodes' displacement solves `A_FF u_F = -A_FH u_H`, where `A` is the tangent stiffness of the tissue at its current state (each
//! spring's `k_t u u^T + (T / L)(I - u u^T)`, the geometric part clamped at zero for compressed springs, plus
//! every free node's anchor, and the volume terms below). The solve covers the nodes within `rings` graph steps of the held ones; nodes
//! beyond, and fixed nodes, are held still. The normal stiffness is the energy of the relaxed mode,
//! `k_n = u^T A u` (the Schur complement of `A` on the tool's motion), non-negative by construction, so `K` is
//! symmetric positive semi-definite. `d_n = u^T C u` is the damping of the same mode moving at unit speed
//! (edge dampers `c u u^T`, and each node's drag `m drag`). With the held set fixed this is the contact's
//! stiffness at the instant; as the tool goes deeper more nodes are caught, which a quasi-static press feels
//! as a softer slope (the pad: `k_n` 0.7 N/mm against a 0.2 N/mm slope at 5 mm). Overestimating `K` errs on
//! the stable side: the part of the force the model does not predict arrives late, and a late negative
//! stiffness acts as damping, where a late positive one would pump energy in.
//!
//! Volume terms. Every tetrahedron touching the local set enters `A` with its current volume gradients `g`:
//! a mass-spring object's per-tetrahedron term as `kappa / V0 g g^T` (Gauss-Newton, as implicit Euler
//! solves it); a finite-element object's elements as their corotational deviatoric stiffness `R K0 R^T`
//! (rotation frozen at the solve's state) and its nodal volume term as `kappa / V_a0 g_a g_a^T` per node `a`
//! of those tetrahedra (`g_a` the sum of its tetrahedra's gradients over four, summed only over the local
//! ones, so the nodes at the edge of the set see part of their volume: a slightly soft edge). Finite
//! elements' springs carry no stiffness, so without this an FEM object's `K` would be zero. The global
//! (closed-surface) volume term is left out (the shipped objects that use it are far from incompressible).
//! How the held set changes as the tool moves, and how the tool normals turn, are left out too (second order
//! at the forces a hand applies).
//!
//! The solve is a Jacobi-preconditioned conjugate gradient, run
//! [`ContactStiffness::ITERATIONS_PER_TICK`] iterations a tick; a finished solve publishes `K` and `D` and the
//! next tick starts a new one from the then-current state, so the result is at most a few ticks old.
//!
//! Here: the solver's state, its tick-by-tick driver ([`ContactStiffness::advance`]) and its result. Setting
//! up the local problem (which nodes, springs and tetrahedra, and the right-hand sides) is in
//! `local_problem`; the product with `A`, the preconditioner, the CG iterations and the result in `solve`.
//!
//! Must not: move the tissue (it reads the state only) or allocate once its buffers have grown.

use std::cell::RefCell;

use nalgebra::Matrix3;

use crate::tissue::{MassSpringModel, TissueState, Vec3};

mod local_problem;
mod solve;

const NONE: u32 = u32::MAX;

/// Node roles in the local problem.
const FREE: u8 = 0;
const HELD: u8 = 1;
const STILL: u8 = 2;

#[derive(Debug, Clone, Copy)]
struct LocalSpring {
    a: u32,
    b: u32,
    /// Tangent stiffness block, N/mm: xx, yy, zz, xy, xz, yz.
    k: [f32; 6],
    /// Damping along the spring, N s/mm, and its unit direction.
    c: f32,
    dir: Vec3,
}

/// A tetrahedron touching the local set.
#[derive(Debug, Clone, Copy)]
struct LocalTet {
    /// Local indices of its vertices (`NONE`: outside the set, still).
    local: [u32; 4],
    /// Slots of its vertices in the nodal-volume list (finite elements; `NONE` when the list was full).
    pressure: [u32; 4],
    /// Volume gradients at the solve's state, mm^2.
    gradients: [Vec3; 4],
    /// Finite elements: `Dm^-1` (1/mm) and the rotation frozen at the solve's state.
    rest_inverse: Matrix3<f32>,
    rotation: Matrix3<f32>,
    /// Finite elements: 2 mu V0, N mm. Springs' per-tetrahedron term: kappa / V0, N/mm^4.
    modulus: f32,
}

/// Which volume terms the local problem carries.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
enum VolumeTerms {
    /// None (a surface, or tetrahedra without a volume term).
    #[default]
    Off,
    /// The mass-spring model's per-tetrahedron term.
    PerTet,
    /// Finite elements: deviatoric elements and the nodal volume term.
    Fem,
}

/// What a finished solve found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactResponse {
    /// `K`, N/mm, world frame.
    pub stiffness_n_per_mm: Matrix3<f32>,
    /// `D`, N s/mm, world frame.
    pub damping_n_s_per_mm: Matrix3<f32>,
    /// Solved in all three directions (the tool grasps): `K` is full rank. False: `k_n n n^T`.
    pub full: bool,
    /// CG iterations the solve took.
    pub iterations: u32,
    /// Nodes in the local problem.
    pub nodes: u32,
}

impl Default for ContactResponse {
    fn default() -> Self {
        Self {
            stiffness_n_per_mm: Matrix3::zeros(),
            damping_n_s_per_mm: Matrix3::zeros(),
            full: false,
            iterations: 0,
            nodes: 0,
        }
    }
}

/// The solver for one (tool, object) pair, with its scratch.
#[derive(Debug, Clone, Default)]
pub struct ContactStiffness {
    local_of: Vec<u32>,
    nodes: Vec<u32>,
    role: Vec<u8>,
    anchor_n_per_mm: Vec<f32>,
    drag_n_s_per_mm: Vec<f32>,
    springs: Vec<LocalSpring>,
    volume_terms: VolumeTerms,
    tets: Vec<LocalTet>,
    /// Slot of each global node in the nodal-volume list (`NONE`: not in it).
    pressure_of: Vec<u32>,
    pressure_nodes: Vec<u32>,
    /// `kappa / V_a0` of each slot, N/mm^5.
    pressure_modulus: Vec<f32>,
    /// Per-slot scratch of a product: `g_a . v`.
    pressure_sum: RefCell<Vec<f32>>,
    diag: Vec<Vec3>,
    u: [Vec<Vec3>; 3],
    r: [Vec<Vec3>; 3],
    p: [Vec<Vec3>; 3],
    ap: [Vec<Vec3>; 3],
    rz: [f32; 3],
    b_norm: [f32; 3],
    converged: [bool; 3],
    iterations: u32,
    solving: bool,
    /// This solve covers the three axes (a grasp), not only the contact normal.
    full: bool,
    normal: Vec3,
    result: Option<ContactResponse>,
    /// Start each solve from the last one's free displacements when it covers the same local set
    /// ([`Self::warm_started`]).
    warm_start: bool,
    /// The last finished solve's local set and free displacements per direction, and whether it was a grasp's.
    warm_nodes: Vec<u32>,
    warm_u: [Vec<Vec3>; 3],
    warm_full: bool,
    /// Graph steps the local problem covers ([`Self::RINGS`] unless [`Self::with_rings`]).
    rings: u32,
}

impl ContactStiffness {
    /// Graph steps from the held nodes that the local problem covers (pad: 1 mm cells, so about 12 mm
    /// around the dent; the anchors make the response decay within a few mm).
    pub const RINGS: u32 = 8;
    /// CG iterations run per tick (each over the three right-hand sides).
    pub const ITERATIONS_PER_TICK: u32 = 4;
    /// A solve stops after this many iterations even if not converged.
    pub const MAX_ITERATIONS: u32 = 120;
    /// Relative residual at which a right-hand side has converged.
    pub const TOLERANCE: f32 = 1e-3;

    /// Largest local problem, nodes (8 rings around a 4 mm probe on the pad's 1 mm grid is about 600).
    pub const MAX_NODES: usize = 4096;
    /// Largest number of springs in the local problem.
    pub const MAX_SPRINGS: usize = Self::MAX_NODES * 8;
    /// Largest number of tetrahedra in the local problem (a node is on about 20, each on 4 nodes).
    pub const MAX_TETS: usize = Self::MAX_NODES * 6;
    /// Largest number of nodes in the nodal-volume list (the local set and the ring beyond it).
    pub const MAX_PRESSURE_NODES: usize = Self::MAX_NODES * 2;

    /// A solver for an object of `node_count` nodes, with every buffer allocated now at its largest size, so
    /// no tick ever grows one.
    pub fn new(node_count: usize) -> Self {
        let m = Self::MAX_NODES.min(node_count);
        let vectors = || Vec::with_capacity(m);
        Self {
            local_of: vec![NONE; node_count],
            nodes: Vec::with_capacity(m),
            role: Vec::with_capacity(m),
            anchor_n_per_mm: Vec::with_capacity(m),
            drag_n_s_per_mm: Vec::with_capacity(m),
            springs: Vec::with_capacity(Self::MAX_SPRINGS),
            tets: Vec::with_capacity(Self::MAX_TETS.min(node_count * 6)),
            pressure_of: vec![NONE; node_count],
            pressure_nodes: Vec::with_capacity(Self::MAX_PRESSURE_NODES.min(node_count)),
            pressure_modulus: Vec::with_capacity(Self::MAX_PRESSURE_NODES.min(node_count)),
            pressure_sum: RefCell::new(Vec::with_capacity(
                Self::MAX_PRESSURE_NODES.min(node_count),
            )),
            diag: vectors(),
            u: [vectors(), vectors(), vectors()],
            r: [vectors(), vectors(), vectors()],
            p: [vectors(), vectors(), vectors()],
            ap: [vectors(), vectors(), vectors()],
            warm_nodes: Vec::with_capacity(m),
            warm_u: [vectors(), vectors(), vectors()],
            rings: Self::RINGS,
            ..Self::default()
        }
    }

    /// The latest finished result (None before the first solve, and after [`Self::forget`]).
    pub fn response(&self) -> Option<&ContactResponse> {
        self.result.as_ref()
    }

    /// Start each solve from the last finished one's relaxed displacements when the local set is the same
    /// (same held and grasped nodes, so the same nodes in the same order): a grasp's set stays put while the
    /// jaws hold, its state moves a little between solves, and the CG starts near its answer. For a
    /// multi-rate object's step, whose grasp solve otherwise spans steps at a cost of several of them (the
    /// liver: 62 iterations over 1,623 nodes, three directions). The converged result differs from a cold
    /// start's within the solve's tolerance, so the tick's own solves (and their golden traces) stay cold.
    pub fn warm_started(mut self) -> Self {
        self.warm_start = true;
        self
    }

    /// Cover `rings` graph steps around the held nodes instead of [`Self::RINGS`] (a coarse mesh: fewer rings
    /// reach as far).
    pub fn with_rings(mut self, rings: u32) -> Self {
        self.rings = rings;
        self
    }

    /// Drop the result and any solve under way (the tool left the tissue).
    pub fn forget(&mut self) {
        self.result = None;
        self.solving = false;
        self.warm_nodes.clear();
        self.release_marks();
    }

    /// The object's topology changed (a cut) and it now has `node_count` nodes: the solve under way, of the old
    /// topology, is dropped, and so is the warm start; the last finished result stays until a solve on the new
    /// topology finishes (a cut softens the tissue: the old, stiffer `K` errs on the stable side, where none
    /// would render a held lobe as slack). Allocates when the object grew.
    pub fn topology_changed(&mut self, node_count: usize) {
        self.solving = false;
        self.warm_nodes.clear();
        self.release_marks();
        self.local_of.resize(node_count, NONE);
        self.pressure_of.resize(node_count, NONE);
    }

    /// Advance the solve by one tick's budget; start a new one from the current state when none is under way.
    /// `held` are the nodes the tool holds and `tool_normals` the tool's outward normals there; `grasped` are
    /// nodes its jaws hold, which follow the tool's whole motion (a grasp's pull is solved like a press). Returns true
    /// when a solve finished this tick (the result changed). Real-time contract: no allocation once warm,
    /// never panics.
    pub fn advance(
        &mut self,
        model: &MassSpringModel,
        state: &TissueState,
        held: &[u32],
        tool_normals: &[Vec3],
        grasped: &[u32],
        contact_normal: &Vec3,
    ) -> bool {
        if held.is_empty() && grasped.is_empty() {
            self.forget();
            return false;
        }
        if !self.solving {
            self.set_up(model, state, held, tool_normals, grasped, contact_normal);
        }
        for _ in 0..Self::ITERATIONS_PER_TICK {
            if self.converged.iter().all(|&c| c) || self.iterations >= Self::MAX_ITERATIONS {
                self.finish();
                return true;
            }
            self.iterate();
        }
        false
    }

    fn release_marks(&mut self) {
        for &g in &self.nodes {
            if let Some(slot) = self.local_of.get_mut(g as usize) {
                *slot = NONE;
            }
        }
        self.nodes.clear();
        for &g in &self.pressure_nodes {
            if let Some(slot) = self.pressure_of.get_mut(g as usize) {
                *slot = NONE;
            }
        }
        self.pressure_nodes.clear();
        self.pressure_modulus.clear();
    }
}

/// The positive semi-definite part of a symmetric matrix (negative eigenvalues, from an inexact solve, set to
/// zero).
pub fn psd_part(m: &Matrix3<f32>) -> Matrix3<f32> {
    let eigen = nalgebra::SymmetricEigen::new(*m);
    let clipped = eigen.eigenvalues.map(|v| v.max(0.0));
    eigen.eigenvectors * Matrix3::from_diagonal(&clipped) * eigen.eigenvectors.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psd_part_clips_negative_eigenvalues() {
        let m = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.5);
        let p = psd_part(&m);
        let e = nalgebra::SymmetricEigen::new(p).eigenvalues;
        assert!(e.iter().all(|&v| v >= -1e-5), "{e:?}");
        // The positive eigenpair (3, (1,1,0)/sqrt 2) survives.
        let v = Vec3::new(1.0, 1.0, 0.0).normalize();
        assert!(((p * v).dot(&v) - 3.0).abs() < 1e-4);
    }
}

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
//! Must not: move the tissue (it reads the state only) or allocate once its buffers have grown.

use std::cell::RefCell;

use nalgebra::Matrix3;

use crate::tissue::fem::element_deviatoric_product;
use crate::tissue::springs::{spring_tangent, sym_block, sym_block_mul};
use crate::tissue::volume::tet_volume_gradients;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

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
    normal: Vec3,
    result: Option<ContactResponse>,
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
            ..Self::default()
        }
    }

    /// The latest finished result (None before the first solve, and after [`Self::forget`]).
    pub fn response(&self) -> Option<&ContactResponse> {
        self.result.as_ref()
    }

    /// Drop the result and any solve under way (the tool left the tissue).
    pub fn forget(&mut self) {
        self.result = None;
        self.solving = false;
        self.release_marks();
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

    /// The nodal-volume slot of global node `g` (a new one when it has none; `NONE` when the list is full).
    fn pressure_slot(&mut self, g: usize, model: &MassSpringModel) -> u32 {
        let fem = model.fem();
        match self.pressure_of.get(g) {
            Some(&slot) if slot != NONE => slot,
            Some(_) if self.pressure_nodes.len() < Self::MAX_PRESSURE_NODES => {
                let slot = self.pressure_nodes.len() as u32;
                self.pressure_of[g] = slot;
                self.pressure_nodes.push(g as u32);
                // A fixed node's volume counts too: it changes as the free nodes around it move.
                let v0 = fem.node_rest_volume_mm3(g);
                self.pressure_modulus.push(if v0 > 0.0 {
                    fem.bulk_modulus_n_per_mm2() / v0
                } else {
                    0.0
                });
                slot
            }
            _ => NONE,
        }
    }

    /// Add global node `g` to the local problem (false when it is full).
    fn local(&mut self, g: usize, role: u8, model: &MassSpringModel) -> bool {
        if self.nodes.len() >= Self::MAX_NODES.min(self.local_of.len()) {
            return false;
        }
        let l = self.nodes.len() as u32;
        self.local_of[g] = l;
        self.nodes.push(g as u32);
        let role = if model.is_fixed(g) { STILL } else { role };
        self.role.push(role);
        let anchor = if model.is_fixed(g) {
            0.0
        } else {
            model.anchor_stiffness_n_per_mm()
        };
        self.anchor_n_per_mm.push(anchor);
        self.drag_n_s_per_mm
            .push(model.mass_kg()[g] * model.drag_per_s() / crate::tissue::MM_PER_M);
        true
    }

    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    fn set_up(
        &mut self,
        model: &MassSpringModel,
        state: &TissueState,
        held: &[u32],
        tool_normals: &[Vec3],
        grasped: &[u32],
        contact_normal: &Vec3,
    ) {
        self.normal = *contact_normal;
        let n = model.node_count();
        if self.local_of.len() != n {
            self.local_of.clear();
            self.local_of.resize(n, NONE);
        }
        if self.pressure_of.len() != n {
            self.pressure_of.clear();
            self.pressure_of.resize(n, NONE);
        }
        self.release_marks();
        self.role.clear();
        self.anchor_n_per_mm.clear();
        self.drag_n_s_per_mm.clear();
        self.springs.clear();
        self.tets.clear();
        for dir in 0..3 {
            self.u[dir].clear();
        }

        // Held nodes first, with their imposed motion for each basis direction.
        let push_dirs = model.rest_normals();
        for (&g, normal) in held.iter().zip(tool_normals) {
            let g = g as usize;
            if g >= n || self.local_of[g] != NONE || !self.local(g, HELD, model) {
                continue;
            }
            let d = -push_dirs[g];
            let along = normal.dot(&d);
            // Only the contact normal's mode is solved (see the module doc); the other two stay zero.
            let imposed = if along.abs() > 0.2 {
                d * (normal.dot(contact_normal) / along)
            } else {
                Vec3::zeros()
            };
            self.u[0].push(imposed);
            self.u[1].push(Vec3::zeros());
            self.u[2].push(Vec3::zeros());
        }
        // Grasped nodes move rigidly with the jaws: all of the tool's motion is imposed on them.
        for &g in grasped {
            let g = g as usize;
            if g >= n || self.local_of[g] != NONE || !self.local(g, HELD, model) {
                continue;
            }
            self.u[0].push(*contact_normal);
            self.u[1].push(Vec3::zeros());
            self.u[2].push(Vec3::zeros());
        }
        // Rings of free nodes around them (breadth first over the spring graph).
        let mut ring_start = 0;
        for _ in 0..Self::RINGS {
            let ring_end = self.nodes.len();
            if ring_start == ring_end {
                break;
            }
            for l in ring_start..ring_end {
                let g = self.nodes[l] as usize;
                for &s in model.node_springs(g) {
                    let other = model.other_end(s, g);
                    if self.local_of[other] == NONE && self.local(other, FREE, model) {
                        for dir in 0..3 {
                            self.u[dir].push(Vec3::zeros());
                        }
                    }
                }
            }
            ring_start = ring_end;
        }

        // Tangent blocks of every spring touching the local set (an outside end stays still).
        let springs = model.springs();
        let law = model.law();
        let x = &state.positions_mm;
        for l in 0..self.nodes.len() {
            let g = self.nodes[l] as usize;
            for &s in model.node_springs(g) {
                let other = model.other_end(s, g);
                let lo = self.local_of[other];
                // Each spring once: from its lower local index, or from its only local end.
                if lo != NONE && (lo as usize) < l {
                    continue;
                }
                if self.springs.len() >= Self::MAX_SPRINGS {
                    continue;
                }
                let (ia, ib, rest, k, c) = springs.get(s as usize);
                let Some(t) = spring_tangent(law, x[ia], x[ib], rest, k) else {
                    continue;
                };
                self.springs.push(LocalSpring {
                    a: l as u32,
                    b: lo,
                    k: sym_block(t.along_n_per_mm, t.iso_n_per_mm, &t.dir),
                    c,
                    dir: t.dir,
                });
            }
        }

        self.gather_tets(model, x);

        // Jacobi preconditioner over the free nodes.
        let m = self.nodes.len();
        self.diag.clear();
        self.diag.resize(m, Vec3::zeros());
        for l in 0..m {
            self.diag[l] = Vec3::repeat(self.anchor_n_per_mm[l]);
            if self.volume_terms == VolumeTerms::Fem {
                self.diag[l] +=
                    Vec3::repeat(model.fem().node_diagonal_n_per_mm(self.nodes[l] as usize));
            }
        }
        if self.volume_terms == VolumeTerms::PerTet {
            for lt in &self.tets {
                for (k, &l) in lt.local.iter().enumerate() {
                    if l != NONE {
                        self.diag[l as usize] += lt.gradients[k].map(|c| c * c) * lt.modulus;
                    }
                }
            }
        }
        for s in &self.springs {
            let d = Vec3::new(s.k[0], s.k[1], s.k[2]);
            self.diag[s.a as usize] += d;
            if s.b != NONE {
                self.diag[s.b as usize] += d;
            }
        }

        // Right-hand sides b = -A_FH u_H (free rows), CG start at u_F = 0.
        for dir in 0..3 {
            for buffer in [&mut self.r[dir], &mut self.p[dir], &mut self.ap[dir]] {
                buffer.clear();
                buffer.resize(m, Vec3::zeros());
            }
        }
        for dir in 0..3 {
            let mut r = std::mem::take(&mut self.r[dir]);
            self.apply(&self.u[dir], &mut r);
            for (l, r) in r.iter_mut().enumerate() {
                *r = if self.role[l] == FREE {
                    -*r
                } else {
                    Vec3::zeros()
                };
            }
            self.r[dir] = r;
            let mut rz = 0.0;
            for l in 0..m {
                let z = self.precondition(l, &self.r[dir][l]);
                self.p[dir][l] = z;
                rz += self.r[dir][l].dot(&z);
            }
            self.rz[dir] = rz;
            self.b_norm[dir] = self.r[dir]
                .iter()
                .map(|v| v.norm_squared())
                .sum::<f32>()
                .sqrt();
            self.converged[dir] = self.b_norm[dir].is_nan() || self.b_norm[dir] <= 1e-12;
        }
        self.iterations = 0;
        self.solving = true;
    }

    /// Every tetrahedron touching the local set, with what its volume terms need at `x`.
    fn gather_tets(&mut self, model: &MassSpringModel, x: &[Vec3]) {
        let fem = model.fem();
        let volumes = model.tets();
        self.volume_terms = if fem.is_on() {
            VolumeTerms::Fem
        } else if volumes.bulk_modulus_n_per_mm2 > 0.0 {
            VolumeTerms::PerTet
        } else {
            VolumeTerms::Off
        };
        if self.volume_terms == VolumeTerms::Off {
            return;
        }
        let two_mu = 2.0 * fem.shear_modulus_n_per_mm2();
        for l in 0..self.nodes.len() {
            let g = self.nodes[l] as usize;
            for &t in model.node_tets(g) {
                let t = t as usize;
                let Some(&tet) = volumes.tets.get(t) else {
                    continue;
                };
                let local = tet.map(|i| self.local_of[i as usize]);
                // Each tetrahedron once: from its lowest local vertex.
                if local.iter().any(|&m| m != NONE && (m as usize) < l) {
                    continue;
                }
                // The bound `new` allocated for (a mesh has about 5 tetrahedra per node).
                if self.tets.len() >= Self::MAX_TETS.min(self.local_of.len() * 6) {
                    continue;
                }
                let v0 = volumes.rest_volume_mm3[t];
                let lt = if self.volume_terms == VolumeTerms::Fem {
                    LocalTet {
                        local,
                        pressure: tet.map(|i| self.pressure_slot(i as usize, model)),
                        gradients: tet_volume_gradients(x, tet),
                        rest_inverse: fem.rest_inverse(t),
                        rotation: fem.rotation(t, tet, x),
                        modulus: two_mu * v0,
                    }
                } else {
                    LocalTet {
                        local,
                        pressure: [NONE; 4],
                        gradients: tet_volume_gradients(x, tet),
                        rest_inverse: Matrix3::zeros(),
                        rotation: Matrix3::identity(),
                        modulus: volumes.bulk_modulus_n_per_mm2 / v0.max(1e-12),
                    }
                };
                self.tets.push(lt);
            }
        }
        let mut sums = self.pressure_sum.borrow_mut();
        sums.clear();
        sums.resize(self.pressure_nodes.len(), 0.0);
    }

    /// `out += A_vol v`: the volume terms' part of the product.
    fn apply_volume(&self, v: &[Vec3], out: &mut [Vec3]) {
        let at = |l: u32| {
            if l == NONE {
                Vec3::zeros()
            } else {
                v[l as usize]
            }
        };
        match self.volume_terms {
            VolumeTerms::Off => {}
            VolumeTerms::PerTet => {
                for lt in &self.tets {
                    let q: f32 = (0..4).map(|k| lt.gradients[k].dot(&at(lt.local[k]))).sum();
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += lt.gradients[k] * (q * lt.modulus);
                        }
                    }
                }
            }
            VolumeTerms::Fem => {
                let mut sums = self.pressure_sum.borrow_mut();
                sums.iter_mut().for_each(|s| *s = 0.0);
                for lt in &self.tets {
                    let p = lt.local.map(at);
                    let y =
                        element_deviatoric_product(&lt.rest_inverse, &lt.rotation, &p, lt.modulus);
                    let mut q = 0.0;
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += y[k];
                        }
                        q += lt.gradients[k].dot(&p[k]);
                    }
                    for &slot in &lt.pressure {
                        if let Some(s) = sums.get_mut(slot as usize) {
                            *s += q / 4.0;
                        }
                    }
                }
                for (s, &k) in sums.iter_mut().zip(&self.pressure_modulus) {
                    *s *= k;
                }
                for lt in &self.tets {
                    let w: f32 = lt
                        .pressure
                        .iter()
                        .filter_map(|&slot| sums.get(slot as usize))
                        .sum::<f32>()
                        / 4.0;
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += lt.gradients[k] * w;
                        }
                    }
                }
            }
        }
    }

    fn precondition(&self, l: usize, r: &Vec3) -> Vec3 {
        if self.role[l] != FREE {
            return Vec3::zeros();
        }
        let d = self.diag[l];
        Vec3::new(
            r.x / d.x.max(1e-9),
            r.y / d.y.max(1e-9),
            r.z / d.z.max(1e-9),
        )
    }

    /// `out = A v` over the local set (outside ends count as still).
    fn apply(&self, v: &[Vec3], out: &mut [Vec3]) {
        for (l, o) in out.iter_mut().enumerate() {
            *o = v[l] * self.anchor_n_per_mm[l];
        }
        for s in &self.springs {
            let va = v[s.a as usize];
            let vb = if s.b == NONE {
                Vec3::zeros()
            } else {
                v[s.b as usize]
            };
            let y = sym_block_mul(&s.k, &(va - vb));
            out[s.a as usize] += y;
            if s.b != NONE {
                out[s.b as usize] -= y;
            }
        }
        self.apply_volume(v, out);
    }

    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    fn iterate(&mut self) {
        let m = self.nodes.len();
        for dir in 0..3 {
            if self.converged[dir] {
                continue;
            }
            let mut ap = std::mem::take(&mut self.ap[dir]);
            self.apply(&self.p[dir], &mut ap);
            let mut pap = 0.0;
            for l in 0..m {
                if self.role[l] == FREE {
                    pap += self.p[dir][l].dot(&ap[l]);
                }
            }
            if pap.is_nan() || pap <= 1e-20 {
                self.converged[dir] = true;
                self.ap[dir] = ap;
                continue;
            }
            let alpha = self.rz[dir] / pap;
            let mut rz_new = 0.0;
            let mut r_norm2 = 0.0;
            for l in 0..m {
                if self.role[l] != FREE {
                    continue;
                }
                self.u[dir][l] += self.p[dir][l] * alpha;
                self.r[dir][l] -= ap[l] * alpha;
                let z = self.precondition(l, &self.r[dir][l]);
                rz_new += self.r[dir][l].dot(&z);
                r_norm2 += self.r[dir][l].norm_squared();
            }
            let beta = rz_new / self.rz[dir];
            for l in 0..m {
                if self.role[l] == FREE {
                    let z = self.precondition(l, &self.r[dir][l]);
                    self.p[dir][l] = z + self.p[dir][l] * beta;
                }
            }
            self.rz[dir] = rz_new;
            self.ap[dir] = ap;
            if r_norm2.sqrt() <= Self::TOLERANCE * self.b_norm[dir] || !rz_new.is_finite() {
                self.converged[dir] = true;
            }
        }
        self.iterations += 1;
    }

    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    fn finish(&mut self) {
        let m = self.nodes.len();
        // k_n = u . A u and d_n = u . C u of the normal mode; K = k_n n n^T, D = d_n n n^T.
        let mut au = std::mem::take(&mut self.ap[0]);
        self.apply(&self.u[0], &mut au);
        let mut k_n = 0.0;
        let mut d_n = 0.0;
        for l in 0..m {
            k_n += self.u[0][l].dot(&au[l]);
            d_n += self.drag_n_s_per_mm[l] * self.u[0][l].norm_squared();
        }
        for s in &self.springs {
            let ua = self.u[0][s.a as usize];
            let ub = if s.b == NONE {
                Vec3::zeros()
            } else {
                self.u[0][s.b as usize]
            };
            d_n += s.c * (ua - ub).dot(&s.dir).powi(2);
        }
        self.ap[0] = au;
        let nn = self.normal * self.normal.transpose();
        let finite = k_n.is_finite() && d_n.is_finite();
        self.result = Some(ContactResponse {
            stiffness_n_per_mm: if finite {
                nn * k_n.max(0.0)
            } else {
                Matrix3::zeros()
            },
            damping_n_s_per_mm: if finite {
                nn * d_n.max(0.0)
            } else {
                Matrix3::zeros()
            },
            iterations: self.iterations,
            nodes: m as u32,
        });
        self.solving = false;
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

//! The mass-spring model of one object: topology and material, immutable after build.
//!
//! Owns: node masses and rest positions, the springs ([`SpringSet`]), the spring law, anchors to rest, drag,
//! gravity, fixed nodes, the surface triangles, optional volume terms (global and per tetrahedron), and the
//! node adjacency every integrator and the region tracker walk. Must not: know about tools or time stepping.
//!
//! Here: the parts a model is made of and the model's accessors. Building it (from a world's object or
//! from parts, and back to parts) is in `build`; the forces and energy it computes in `forces`; the
//! Gershgorin rates the stability analysis reads in `rates`.

use std::sync::Arc;

use super::fem::{FemElements, FemMaterial, NodeTets};
use super::springs::{KernelScratch, SpringSet};
use super::volume::{GlobalVolume, TetVolumes};
use super::{SpringLaw, Vec3};
use sinew_parallel::{ChunkRunner, Inline, ScratchCell};

mod build;
mod forces;
mod rates;

/// Everything a model is built from. Public so tests and the region tracker can build models that are not
/// loaded from a world file (a hanging chain, a sub-model of the moving region).
#[derive(Debug, Clone, Default)]
pub struct ModelParts {
    /// Rest positions, mm.
    pub rest_positions_mm: Vec<Vec3>,
    /// Node masses, kg.
    pub mass_kg: Vec<f32>,
    /// Fixed nodes never move.
    pub fixed: Vec<bool>,
    /// Springs as (a, b) with a < b; rest lengths come from the rest positions.
    pub edges: Vec<[u32; 2]>,
    /// Per-edge stiffness, N/mm (same length as `edges`).
    pub edge_stiffness_n_per_mm: Vec<f32>,
    /// Per-edge damping, N s/mm (same length as `edges`).
    pub edge_damping_n_s_per_mm: Vec<f32>,
    /// Tension law of every spring.
    pub law: Option<SpringLaw>,
    /// Spring from each free node to its rest position, N/mm.
    pub anchor_stiffness_n_per_mm: f32,
    /// Viscous drag, 1/s.
    pub drag_per_s: f32,
    /// Uniform acceleration of every free node, mm/s^2.
    pub gravity_mm_per_s2: Vec3,
    /// Surface triangles (outward winding); may be empty (a chain).
    pub triangles: Vec<[u32; 3]>,
    /// Tetrahedra (any orientation; reoriented at build).
    pub tets: Vec<[u32; 4]>,
    /// Bulk modulus of the per-tetrahedron volume term, N/mm^2 (0 = off).
    pub tet_bulk_modulus_n_per_mm2: f32,
    /// Bulk modulus of the global volume term, N/mm^2 (0 = off; needs a closed surface).
    pub global_bulk_modulus_n_per_mm2: f32,
    /// Corotational finite elements on the tetrahedra (`None`: none; the springs carry the elasticity).
    pub fem: Option<FemMaterial>,
}

/// Nodes are point masses; springs are spring-dampers along edges; every free node also has an anchor spring
/// to its rest position (the tissue underneath); fixed nodes never move.
#[derive(Debug, Clone)]
pub struct MassSpringModel {
    /// Unique per built model (see [`Self::id`]).
    id: u64,
    rest_positions_mm: Vec<Vec3>,
    rest_normals: Vec<Vec3>,
    mass_kg: Vec<f32>,
    /// 1000 / mass for free nodes (mm/s^2 per N), 0 for fixed nodes.
    accel_per_force: Vec<f32>,
    springs: SpringSet,
    law: SpringLaw,
    anchor_stiffness_n_per_mm: f32,
    drag_per_s: f32,
    gravity_mm_per_s2: Vec3,
    triangles: Vec<[u32; 3]>,
    tets: TetVolumes,
    /// Finite elements on the tetrahedra (empty for a pure mass-spring object).
    fem: FemElements,
    global_volume: Option<GlobalVolume>,
    /// CSR node -> incident springs.
    node_spring_start: Vec<u32>,
    node_springs: Vec<u32>,
    /// CSR node -> incident triangles, and node -> incident tetrahedra.
    node_triangle_start: Vec<u32>,
    node_triangles: Vec<u32>,
    node_tet_start: Vec<u32>,
    node_tets: Vec<u32>,
    /// Small-strain stiffness diagonal per node (incident springs plus anchor), N/mm.
    diagonal_stiffness_n_per_mm: Vec<f32>,
    /// Scratch of [`Self::rebuild_from`]: the spring sort order.
    build_order: Vec<usize>,
    /// The spring kernel's padded buffers: scratch, not state (a model is stepped by one thread at a time;
    /// `compute_forces` stays `&self` so every integrator shares one model, and the model stays `Sync` so the
    /// tools' contact solves read it from several threads).
    kernel_scratch: ScratchCell<KernelScratch>,
    /// The threads the spring passes and the integration spread over (`None`: the calling thread alone). Not
    /// part of the model's physics: any runner gives the same bits.
    runner: Option<Arc<dyn ChunkRunner>>,
}

impl MassSpringModel {
    /// An id no other model built in this process has (a clone keeps it: same topology). Caches keyed on a
    /// model (XPBD's edge colouring) use it, so two sub-models of equal size never share a cache entry.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.rest_positions_mm.len()
    }

    /// Number of edges (springs).
    pub fn edge_count(&self) -> usize {
        self.springs.len()
    }

    /// Nodes that can move.
    pub fn free_node_count(&self) -> usize {
        self.accel_per_force.iter().filter(|w| **w > 0.0).count()
    }

    /// Whether node `i` is fixed.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.accel_per_force[i] == 0.0
    }

    /// Rest positions, mm.
    pub fn rest_positions_mm(&self) -> &[Vec3] {
        &self.rest_positions_mm
    }

    /// Outward unit normal at each node at rest (area-weighted, from the triangle winding; +z for nodes on
    /// no triangle).
    pub fn rest_normals(&self) -> &[Vec3] {
        &self.rest_normals
    }

    /// Surface triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Tetrahedra and their volume term.
    pub fn tets(&self) -> &TetVolumes {
        &self.tets
    }

    /// The finite elements (empty unless the object is `fem-corotational`).
    pub fn fem(&self) -> &FemElements {
        &self.fem
    }

    /// The tetrahedra around each node.
    pub fn node_tets_csr(&self) -> NodeTets<'_> {
        NodeTets {
            start: &self.node_tet_start,
            tets: &self.node_tets,
        }
    }

    /// The global volume term, if on.
    pub fn global_volume(&self) -> Option<&GlobalVolume> {
        self.global_volume.as_ref()
    }

    /// Node masses, kg.
    pub fn mass_kg(&self) -> &[f32] {
        &self.mass_kg
    }

    /// Set free node `i`'s mass to `kg` (above 0) in place: its acceleration per newton follows. A fixed node,
    /// an index out of range or a mass not above 0 changes nothing. (Mass scaling after a cut: no rebuild.)
    pub fn set_node_mass(&mut self, i: usize, kg: f32) {
        if i < self.node_count() && self.accel_per_force[i] > 0.0 && kg > 0.0 && kg.is_finite() {
            self.mass_kg[i] = kg;
            self.accel_per_force[i] = crate::tissue::MM_PER_M / kg;
        }
    }

    /// mm/s^2 per newton for each node (0 for fixed nodes).
    pub fn accel_per_force(&self) -> &[f32] {
        &self.accel_per_force
    }

    /// Viscous drag, 1/s.
    pub fn drag_per_s(&self) -> f32 {
        self.drag_per_s
    }

    /// Uniform acceleration, mm/s^2.
    pub fn gravity_mm_per_s2(&self) -> Vec3 {
        self.gravity_mm_per_s2
    }

    /// Anchor stiffness, N/mm.
    pub fn anchor_stiffness_n_per_mm(&self) -> f32 {
        self.anchor_stiffness_n_per_mm
    }

    /// The springs.
    pub fn springs(&self) -> &SpringSet {
        &self.springs
    }

    /// The spring law.
    pub fn law(&self) -> SpringLaw {
        self.law
    }

    /// Springs incident to node `i`.
    pub fn node_springs(&self, i: usize) -> &[u32] {
        &self.node_springs
            [self.node_spring_start[i] as usize..self.node_spring_start[i + 1] as usize]
    }

    /// The node at the other end of spring `s` from node `i`.
    pub fn other_end(&self, s: u32, i: usize) -> usize {
        let (a, b) = (
            self.springs.a[s as usize] as usize,
            self.springs.b[s as usize] as usize,
        );
        if a == i { b } else { a }
    }

    /// Set spring `s`'s rest length to `share` of its ends' distance at rest (tissue that shrinks, as burnt
    /// tissue does); `share` is clamped to 0.1..=1. No allocation.
    pub fn set_spring_rest_share(&mut self, s: u32, share: f32) {
        let s = s as usize;
        let (Some(&a), Some(&b)) = (self.springs.a.get(s), self.springs.b.get(s)) else {
            return;
        };
        let rest_mm =
            (self.rest_positions_mm[a as usize] - self.rest_positions_mm[b as usize]).norm();
        self.springs.rest_mm[s] = rest_mm * share.clamp(0.1, 1.0);
    }

    /// Triangles incident to node `i`.
    pub fn node_triangles(&self, i: usize) -> &[u32] {
        &self.node_triangles
            [self.node_triangle_start[i] as usize..self.node_triangle_start[i + 1] as usize]
    }

    /// The outward normal at node `i` with the nodes at `positions_mm`: area-weighted over its triangles (the
    /// rest normal if it has none or they are degenerate; zero for a node out of range).
    pub fn current_normal(&self, positions_mm: &[Vec3], i: usize) -> Vec3 {
        let at = |v: u32| {
            positions_mm
                .get(v as usize)
                .copied()
                .unwrap_or_else(Vec3::zeros)
        };
        let mut n = Vec3::zeros();
        for &t in self
            .node_triangles
            .get(
                self.node_triangle_start.get(i).map_or(0, |&s| s as usize)
                    ..self
                        .node_triangle_start
                        .get(i + 1)
                        .map_or(0, |&e| e as usize),
            )
            .unwrap_or(&[])
        {
            let [a, b, c] = self.triangles[t as usize].map(at);
            n += (b - a).cross(&(c - a));
        }
        let len = n.norm();
        if len > 1e-9 && len.is_finite() {
            n / len
        } else {
            self.rest_normals
                .get(i)
                .copied()
                .unwrap_or_else(Vec3::zeros)
        }
    }

    /// Tetrahedra incident to node `i` (indices into [`Self::tets`]).
    pub fn node_tets(&self, i: usize) -> &[u32] {
        &self.node_tets[self.node_tet_start[i] as usize..self.node_tet_start[i + 1] as usize]
    }

    /// Spread this model's passes over `runner` (`None`: the calling thread alone). Results are the same bits
    /// either way; only the time changes.
    pub fn set_chunk_runner(&mut self, runner: Option<Arc<dyn ChunkRunner>>) {
        self.runner = runner;
    }

    /// The runner this model's passes use.
    pub fn chunk_runner(&self) -> &dyn ChunkRunner {
        match &self.runner {
            Some(runner) => runner.as_ref(),
            None => &Inline,
        }
    }

    /// The runner as shared (for a model built from this one, the region's sub-model, say).
    pub fn shared_chunk_runner(&self) -> Option<&Arc<dyn ChunkRunner>> {
        self.runner.as_ref()
    }

    /// Sum over incident springs of their small-strain stiffness, plus the anchor: the diagonal of the
    /// stiffness matrix at rest, N/mm (quasi-static relaxation divides by it).
    pub fn diagonal_stiffness_n_per_mm(&self, i: usize) -> f32 {
        self.diagonal_stiffness_n_per_mm[i]
    }
}

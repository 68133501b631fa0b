//! The mass-spring model of one object: topology and material, immutable after build.
//!
//! Owns: node masses and rest positions, the springs ([`SpringSet`]), the spring law, anchors to rest, drag,
//! gravity, fixed nodes, the surface triangles, optional volume terms (global and per tetrahedron), and the
//! node adjacency every integrator and the region tracker walk. Must not: know about tools or time stepping.

use std::sync::atomic::{AtomicU64, Ordering};

use std::sync::Arc;

use super::fem::{FemElements, FemLinearization, FemMaterial, NodeTets};
use super::springs::{ForcePass, KernelScratch, NodeSprings, SpringSet};
use super::volume::{GlobalVolume, TetVolumes};
use super::{MM_PER_M, SpringLaw, Vec3};
use super::{MassSpec, ObjectSpec};
use crate::incidence::incidence_into;
use sinew_parallel::{ChunkRunner, Inline, ScratchCell};

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

/// Source of [`MassSpringModel::id`].
static NEXT_MODEL_ID: AtomicU64 = AtomicU64::new(1);

/// `dst = src`, reusing `dst`'s buffer.
fn refill<T: Copy>(dst: &mut Vec<T>, src: &[T]) {
    dst.clear();
    dst.extend_from_slice(src);
}

impl MassSpringModel {
    /// Build from a validated object spec: masses by vertex area share, springs along the unique mesh edges
    /// (and tetrahedron edges), gravity from the world.
    pub fn build(spec: &ObjectSpec, gravity_mm_per_s2: Vec3) -> Self {
        let positions: Vec<Vec3> = spec
            .mesh
            .positions_mm
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let n = positions.len();
        let triangles = spec.mesh.triangles.clone();
        let tets = spec.tets.clone();

        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(triangles.len() * 3 + tets.len() * 6);
        for tri in &triangles {
            for k in 0..3 {
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                edges.push([p.min(q), p.max(q)]);
            }
        }
        for tet in &tets {
            for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let (p, q) = (tet[i], tet[j]);
                edges.push([p.min(q), p.max(q)]);
            }
        }
        edges.sort_unstable();
        edges.dedup();

        // Mass shares: by tetrahedron volume when the object has tetrahedra, else by triangle area.
        let mut share = vec![0.0f32; n];
        if tets.is_empty() {
            for tri in &triangles {
                let [a, b, c] = tri.map(|v| positions[v as usize]);
                let area = 0.5 * (b - a).cross(&(c - a)).norm();
                for v in tri {
                    share[*v as usize] += area / 3.0;
                }
            }
        } else {
            for tet in &tets {
                let v = super::volume::tet_volume_mm3(&positions, *tet).abs();
                for i in tet {
                    share[*i as usize] += v / 4.0;
                }
            }
        }
        let total_share: f32 = share.iter().sum();
        let mass_kg: Vec<f32> = match spec.material.mass {
            MassSpec::TotalKg(total) => share.iter().map(|a| total * a / total_share).collect(),
            MassSpec::Density {
                kg_per_m3,
                thickness_mm,
            } => {
                // Sheets: area x thickness; volumes: the volume itself.
                let depth = if tets.is_empty() { thickness_mm } else { 1.0 };
                share.iter().map(|a| a * depth * kg_per_m3 * 1e-9).collect()
            }
        };
        let fixed = spec
            .mesh
            .positions_mm
            .iter()
            .map(|p| spec.fixed.iter().any(|s| s.contains(*p)))
            .collect();
        let m = &spec.material;
        let (edge_stiffness_n_per_mm, volume_supplement_n_per_mm2) = match m.calibrated {
            Some(c) => (
                super::calibration::calibrated_edge_stiffness(
                    &positions,
                    &edges,
                    &tets,
                    &triangles,
                    c.youngs_modulus_n_per_mm2,
                    c.poisson_ratio,
                    c.thickness_mm,
                ),
                if tets.is_empty() {
                    0.0
                } else {
                    super::calibration::volume_supplement_n_per_mm2(
                        c.youngs_modulus_n_per_mm2,
                        c.poisson_ratio,
                    )
                    .max(0.0)
                },
            ),
            None => (vec![m.stiffness_n_per_mm; edges.len()], 0.0),
        };
        Self::from_parts(ModelParts {
            rest_positions_mm: positions,
            mass_kg,
            fixed,
            edge_stiffness_n_per_mm,
            edge_damping_n_s_per_mm: vec![m.damping_n_s_per_mm; edges.len()],
            edges,
            law: Some(m.law),
            anchor_stiffness_n_per_mm: m.anchor_stiffness_n_per_mm,
            drag_per_s: m.drag_per_s,
            gravity_mm_per_s2,
            triangles,
            tets,
            tet_bulk_modulus_n_per_mm2: m.tet_bulk_modulus_n_per_mm2 + volume_supplement_n_per_mm2,
            global_bulk_modulus_n_per_mm2: m.global_bulk_modulus_n_per_mm2,
            fem: m.fem,
        })
    }

    /// Build from parts (indices must be in range; edges with `a < b`).
    pub fn from_parts(parts: ModelParts) -> Self {
        let mut model = Self::empty();
        model.rebuild_from(&parts);
        model
    }

    /// A model with no nodes, to be filled by [`Self::rebuild_from`].
    fn empty() -> Self {
        Self {
            id: 0,
            rest_positions_mm: Vec::new(),
            rest_normals: Vec::new(),
            mass_kg: Vec::new(),
            accel_per_force: Vec::new(),
            springs: SpringSet::default(),
            law: SpringLaw::Linear,
            anchor_stiffness_n_per_mm: 0.0,
            drag_per_s: 0.0,
            gravity_mm_per_s2: Vec3::zeros(),
            triangles: Vec::new(),
            tets: TetVolumes::default(),
            fem: FemElements::default(),
            global_volume: None,
            node_spring_start: Vec::new(),
            node_springs: Vec::new(),
            node_triangle_start: Vec::new(),
            node_triangles: Vec::new(),
            node_tet_start: Vec::new(),
            node_tets: Vec::new(),
            diagonal_stiffness_n_per_mm: Vec::new(),
            kernel_scratch: ScratchCell::default(),
            build_order: Vec::new(),
            runner: None,
        }
    }

    /// Refill this model from `parts` in place, reusing every buffer: allocates only where `parts` is larger
    /// than anything this model held before (the region tracker rebuilds its sub-model inside a tick this
    /// way). The model gets a new [`Self::id`]. Indices must be in range; edges with `a < b`.
    pub fn rebuild_from(&mut self, parts: &ModelParts) {
        let n = parts.rest_positions_mm.len();
        self.id = NEXT_MODEL_ID.fetch_add(1, Ordering::Relaxed);
        refill(&mut self.rest_positions_mm, &parts.rest_positions_mm);
        refill(&mut self.mass_kg, &parts.mass_kg);
        refill(&mut self.triangles, &parts.triangles);
        self.law = parts.law.unwrap_or(SpringLaw::Linear);
        self.anchor_stiffness_n_per_mm = parts.anchor_stiffness_n_per_mm;
        self.drag_per_s = parts.drag_per_s;
        self.gravity_mm_per_s2 = parts.gravity_mm_per_s2;
        let positions = &self.rest_positions_mm;

        self.build_order.clear();
        self.build_order.extend(0..parts.edges.len());
        // Parts made from a model (a cut's) come sorted already: checking is one pass, sorting is not.
        if !parts.edges.is_sorted() {
            self.build_order.sort_unstable_by_key(|&e| parts.edges[e]);
        }
        self.springs.clear();
        for &e in &self.build_order {
            let [a, b] = parts.edges[e];
            self.springs.push(
                a,
                b,
                (positions[b as usize] - positions[a as usize]).norm(),
                parts.edge_stiffness_n_per_mm[e],
                parts.edge_damping_n_s_per_mm[e],
            );
        }
        let springs = &self.springs;
        incidence_into(
            n,
            springs.len(),
            |s| [springs.a[s], springs.b[s]],
            &mut self.node_spring_start,
            &mut self.node_springs,
        );
        let triangles = &self.triangles;
        incidence_into(
            n,
            triangles.len(),
            |t| triangles[t],
            &mut self.node_triangle_start,
            &mut self.node_triangles,
        );

        self.rest_normals.clear();
        self.rest_normals.resize(n, Vec3::zeros());
        for tri in triangles {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            let area_normal = 0.5 * (b - a).cross(&(c - a));
            for v in tri {
                self.rest_normals[*v as usize] += area_normal;
            }
        }
        for normal in &mut self.rest_normals {
            *normal = normal.try_normalize(1e-12).unwrap_or_else(Vec3::z);
        }
        self.accel_per_force.clear();
        self.accel_per_force.extend(
            parts
                .mass_kg
                .iter()
                .zip(&parts.fixed)
                .map(|(m, &f)| if f || *m <= 0.0 { 0.0 } else { MM_PER_M / m }),
        );
        self.tets
            .refill(&parts.tets, positions, parts.tet_bulk_modulus_n_per_mm2);
        self.fem.refill(parts.fem, &self.tets, positions);
        let tets = &self.tets.tets;
        incidence_into(
            n,
            tets.len(),
            |t| tets[t],
            &mut self.node_tet_start,
            &mut self.node_tets,
        );
        self.global_volume = (parts.global_bulk_modulus_n_per_mm2 > 0.0).then(|| GlobalVolume {
            rest_volume_mm3: super::volume::enclosed_volume_mm3(positions, triangles),
            bulk_modulus_n_per_mm2: parts.global_bulk_modulus_n_per_mm2,
        });
        let (start, list) = (&self.node_spring_start, &self.node_springs);
        self.diagonal_stiffness_n_per_mm.clear();
        self.diagonal_stiffness_n_per_mm.extend((0..n).map(|i| {
            list[start[i] as usize..start[i + 1] as usize]
                .iter()
                .map(|&s| springs.stiffness_n_per_mm[s as usize])
                .sum::<f32>()
                + parts.anchor_stiffness_n_per_mm
                + self.fem.node_diagonal_n_per_mm(i)
        }));
    }

    /// The parts this model would be rebuilt from: the same nodes, springs (in their sorted order), elements
    /// and material (fixed nodes are those with no acceleration per force). Allocates: for topology changes,
    /// not the tick.
    pub fn to_parts(&self) -> ModelParts {
        let mut parts = ModelParts::default();
        self.to_parts_into(&mut parts);
        parts
    }

    /// [`Self::to_parts`] into `parts`, reusing its buffers (allocates only where this model is larger than
    /// what they held).
    pub fn to_parts_into(&self, parts: &mut ModelParts) {
        let springs = &self.springs;
        refill(&mut parts.rest_positions_mm, &self.rest_positions_mm);
        refill(&mut parts.mass_kg, &self.mass_kg);
        parts.fixed.clear();
        parts
            .fixed
            .extend(self.accel_per_force.iter().map(|&w| w == 0.0));
        parts.edges.clear();
        parts
            .edges
            .extend(springs.a.iter().zip(&springs.b).map(|(&a, &b)| [a, b]));
        refill(
            &mut parts.edge_stiffness_n_per_mm,
            &springs.stiffness_n_per_mm,
        );
        refill(
            &mut parts.edge_damping_n_s_per_mm,
            &springs.damping_n_s_per_mm,
        );
        parts.law = Some(self.law);
        parts.anchor_stiffness_n_per_mm = self.anchor_stiffness_n_per_mm;
        parts.drag_per_s = self.drag_per_s;
        parts.gravity_mm_per_s2 = self.gravity_mm_per_s2;
        refill(&mut parts.triangles, &self.triangles);
        refill(&mut parts.tets, &self.tets.tets);
        parts.tet_bulk_modulus_n_per_mm2 = self.tets.bulk_modulus_n_per_mm2;
        parts.global_bulk_modulus_n_per_mm2 = self
            .global_volume
            .as_ref()
            .map_or(0.0, |g| g.bulk_modulus_n_per_mm2);
        parts.fem = self.fem.material();
    }

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

    /// Force on every node except drag (springs with their dampers, anchors, gravity, volume terms, plus
    /// `external_n` if given), N, written into `forces_n`. Returns the global-volume pressure (0 if off).
    /// Real-time contract: no allocation once warm, never panics on non-finite input.
    pub fn compute_forces(
        &self,
        positions_mm: &[Vec3],
        velocities_mm_s: &[Vec3],
        external_n: Option<&[Vec3]>,
        forces_n: &mut [Vec3],
    ) -> f32 {
        self.forces(
            positions_mm,
            Some(velocities_mm_s),
            external_n,
            forces_n,
            None,
        )
    }

    /// [`Self::compute_forces`] at zero velocity (no damper forces, and no velocity pass): for static
    /// solves (quasi-static relaxation, the implicit integrator's right-hand side).
    pub fn compute_static_forces(
        &self,
        positions_mm: &[Vec3],
        external_n: Option<&[Vec3]>,
        forces_n: &mut [Vec3],
    ) -> f32 {
        self.forces(positions_mm, None, external_n, forces_n, None)
    }

    /// [`Self::compute_static_forces`] that also freezes the finite elements' rotations and volume gradients
    /// at these positions into `fem` (for the implicit integrator's matrix; one polar decomposition per element
    /// serves both).
    pub fn compute_static_forces_linearized(
        &self,
        positions_mm: &[Vec3],
        external_n: Option<&[Vec3]>,
        forces_n: &mut [Vec3],
        fem: &mut FemLinearization,
    ) -> f32 {
        self.forces(positions_mm, None, external_n, forces_n, Some(fem))
    }

    fn forces(
        &self,
        positions_mm: &[Vec3],
        velocities_mm_s: Option<&[Vec3]>,
        external_n: Option<&[Vec3]>,
        forces_n: &mut [Vec3],
        fem: Option<&mut FemLinearization>,
    ) -> f32 {
        let k_anchor = self.anchor_stiffness_n_per_mm;
        let g = self.gravity_mm_per_s2 / MM_PER_M;
        let rest = &self.rest_positions_mm;
        let mass = &self.mass_kg;
        let base = |i: usize| {
            let own = (rest[i] - positions_mm[i]) * k_anchor + g * mass[i];
            match external_n.and_then(|e| e.get(i)) {
                Some(e) => own + e,
                None => own,
            }
        };
        let incidence = NodeSprings {
            start: &self.node_spring_start,
            list: &self.node_springs,
        };
        let pass = ForcePass {
            law: self.law,
            positions_mm,
            velocities_mm_s,
            base_n: base,
        };
        self.kernel_scratch.with(|scratch| {
            self.springs
                .forces_into(pass, forces_n, scratch, self.chunk_runner(), incidence)
        });
        self.tets.accumulate_forces(positions_mm, forces_n);
        self.fem
            .accumulate_forces(&self.tets, positions_mm, forces_n, fem);
        match &self.global_volume {
            Some(global) => global.accumulate_forces(positions_mm, &self.triangles, forces_n),
            None => 0.0,
        }
    }

    /// Energy stored in the springs, the volume terms and the finite elements (not the anchors or gravity),
    /// N mm.
    pub fn elastic_energy_n_mm(&self, positions_mm: &[Vec3]) -> f64 {
        let springs = self.kernel_scratch.with(|scratch| {
            self.springs
                .energy_n_mm(self.law, positions_mm, self.chunk_runner(), scratch)
        });
        let mut total = springs + self.fem.energy_n_mm(&self.tets, positions_mm);
        let tets = &self.tets;
        if tets.bulk_modulus_n_per_mm2 > 0.0 {
            for (t, &v0) in tets.rest_volume_mm3.iter().enumerate() {
                let dv = super::volume::tet_volume_mm3(positions_mm, tets.tets[t]) - v0;
                total += f64::from(0.5 * tets.bulk_modulus_n_per_mm2 * dv * dv / v0);
            }
        }
        if let Some(global) = &self.global_volume {
            let dv = super::volume::enclosed_volume_mm3(positions_mm, &self.triangles)
                - global.rest_volume_mm3;
            total +=
                f64::from(0.5 * global.bulk_modulus_n_per_mm2 * dv * dv / global.rest_volume_mm3);
        }
        total
    }

    /// The global-volume pressure at these positions, N/mm^2 (0 if off). O(triangles).
    pub fn pressure_n_per_mm2(&self, positions_mm: &[Vec3]) -> f32 {
        self.global_volume
            .as_ref()
            .map_or(0.0, |g| g.pressure_n_per_mm2(positions_mm, &self.triangles))
    }

    /// Internal force on node `i` alone (its incident springs, anchor, gravity, volume terms given the global
    /// pressure from [`Self::pressure_n_per_mm2`], finite elements), N. No allocation; a finite-element node
    /// costs two rings of tetrahedra (its elements' nodal pressures).
    pub fn node_force(
        &self,
        i: usize,
        positions_mm: &[Vec3],
        velocities_mm_s: &[Vec3],
        pressure_n_per_mm2: f32,
    ) -> Vec3 {
        let mut f = (self.rest_positions_mm[i] - positions_mm[i]) * self.anchor_stiffness_n_per_mm
            + self.gravity_mm_per_s2 * (self.mass_kg[i] / MM_PER_M);
        for &s in self.node_springs(i) {
            let on_a = self
                .springs
                .force_on_a(self.law, s as usize, positions_mm, velocities_mm_s);
            f += if self.springs.a[s as usize] as usize == i {
                on_a
            } else {
                -on_a
            };
        }
        let tets =
            &self.node_tets[self.node_tet_start[i] as usize..self.node_tet_start[i + 1] as usize];
        for &t in tets {
            let forces = self.tets.forces(t as usize, positions_mm);
            for (k, &v) in self.tets.tets[t as usize].iter().enumerate() {
                if v as usize == i {
                    f += forces[k];
                }
            }
        }
        f += self
            .fem
            .node_force(i, &self.tets, self.node_tets_csr(), positions_mm);
        if self.global_volume.is_some() {
            f += GlobalVolume::vertex_force(
                pressure_n_per_mm2,
                i,
                self.node_triangles(i),
                positions_mm,
                &self.triangles,
            );
        }
        f
    }

    /// Per free node, Gershgorin bounds on the stiffness and edge-damping rates `(w^2, g_edge)`, with
    /// `w^2 = 1000 K / m` and `g_edge = 1000 C / m` (drag is separate: [`Self::drag_per_s`]). `K` sums
    /// `2 k_edge stiffening` over incident springs, the anchor, the finite elements' rows at rest, and the volume terms' Hessian rows at rest
    /// (`K_bulk / V0 |g_i| sum_j |g_j|` per tetrahedron, and the same over the surface for the global term);
    /// `C = 2 sum(c_edge)`. `stiffening` is the law's largest tangent over the strains assumed.
    pub fn node_rates(&self, stiffening: f32) -> impl Iterator<Item = (f32, f32)> + '_ {
        let x = &self.rest_positions_mm;
        let global_gradient_norm = move |i: usize| {
            self.global_volume.map_or(0.0, |_| {
                GlobalVolume::vertex_force(1.0, i, self.node_triangles(i), x, &self.triangles)
                    .norm()
            })
        };
        let global_row: f32 = match &self.global_volume {
            Some(_) => (0..self.node_count()).map(global_gradient_norm).sum(),
            None => 0.0,
        };
        (0..self.node_count()).filter_map(move |i| {
            let w = self.accel_per_force[i];
            if w == 0.0 {
                return None;
            }
            let (mut k, mut c) = (self.anchor_stiffness_n_per_mm, 0.0);
            for &s in self.node_springs(i) {
                k += 2.0 * self.springs.stiffness_n_per_mm[s as usize] * stiffening;
                c += 2.0 * self.springs.damping_n_s_per_mm[s as usize];
            }
            let x = &self.rest_positions_mm;
            if self.tets.bulk_modulus_n_per_mm2 > 0.0 {
                let tets = &self.node_tets
                    [self.node_tet_start[i] as usize..self.node_tet_start[i + 1] as usize];
                for &t in tets {
                    let tet = self.tets.tets[t as usize];
                    let g = super::volume::tet_volume_gradients(x, tet);
                    let own = tet
                        .iter()
                        .position(|&v| v as usize == i)
                        .map_or(0.0, |k| g[k].norm());
                    let row: f32 = g.iter().map(|gj| gj.norm()).sum();
                    k += self.tets.bulk_modulus_n_per_mm2 / self.tets.rest_volume_mm3[t as usize]
                        * own
                        * row;
                }
            }
            k += self.fem.node_row_bound_n_per_mm(i);
            if let Some(global) = &self.global_volume {
                k += global.bulk_modulus_n_per_mm2 / global.rest_volume_mm3
                    * global_gradient_norm(i)
                    * global_row;
            }
            Some((w * k, w * c))
        })
    }
}

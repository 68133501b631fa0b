//! Building a model: from a world's object spec, from parts (in place, reusing every buffer), and back to
//! parts.
//!
//! Owns: masses from area or volume shares, the unique edges, calibrated stiffness, the sorted springs and
//! every adjacency table, the elements' rest data, and each model's id. Must not: compute forces or step
//! anything (a built model is immutable until the next rebuild).

use std::sync::atomic::{AtomicU64, Ordering};

use super::*;
use crate::incidence::incidence_into;
use crate::tissue::{MM_PER_M, MassSpec, ObjectSpec};

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
                let v = crate::tissue::volume::tet_volume_mm3(&positions, *tet).abs();
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
                crate::tissue::calibration::calibrated_edge_stiffness(
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
                    crate::tissue::calibration::volume_supplement_n_per_mm2(
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
            rest_volume_mm3: crate::tissue::volume::enclosed_volume_mm3(positions, triangles),
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
}

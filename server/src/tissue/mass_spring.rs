//! The mass-spring model of one object: topology and material, immutable after build.

use super::{MM_PER_M, Vec3};
use crate::world::{MassSpec, ObjectSpec};

/// One spring-damper along a mesh edge, laid out together so the force loop touches one line per edge.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Spring {
    a: u32,
    b: u32,
    rest_length_mm: f32,
    stiffness_n_per_mm: f32,
    damping_n_s_per_mm: f32,
}

/// Nodes are point masses at the mesh vertices; edges are spring-dampers along the unique mesh edges; every
/// free node also has an anchor spring to its rest position (the tissue underneath); fixed nodes never move.
#[derive(Debug, Clone)]
pub struct MassSpringModel {
    rest_positions_mm: Vec<Vec3>,
    rest_normals: Vec<Vec3>,
    mass_kg: Vec<f32>,
    /// 1000 / mass for free nodes (mm/s^2 per N), 0 for fixed nodes.
    accel_per_force: Vec<f32>,
    /// Springs, sorted by (a, b) so node accesses stay local.
    springs: Vec<Spring>,
    anchor_stiffness_n_per_mm: f32,
    drag_per_s: f32,
    triangles: Vec<[u32; 3]>,
    /// CSR node -> incident edges.
    node_edge_start: Vec<u32>,
    node_edges: Vec<u32>,
}

impl Spring {
    /// Spring plus damper force on end `a` (end `b` gets the opposite), N. Zero for a zero-length edge.
    #[inline(always)]
    fn force_on_a(&self, x: &[Vec3], v: &[Vec3]) -> Vec3 {
        let (a, b) = (self.a as usize, self.b as usize);
        let d = x[b] - x[a];
        let len = d.norm();
        if len <= 1e-9 {
            return Vec3::zeros();
        }
        let dir = d * (1.0 / len);
        let stretch = len - self.rest_length_mm;
        let rate = (v[b] - v[a]).dot(&dir);
        dir * (self.stiffness_n_per_mm * stretch + self.damping_n_s_per_mm * rate)
    }
}

impl MassSpringModel {
    /// Build from a validated object spec (masses by vertex area share, edges from triangles).
    pub fn build(spec: &ObjectSpec) -> Self {
        let positions: Vec<Vec3> = spec
            .mesh
            .positions_mm
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let n = positions.len();
        let triangles = spec.mesh.triangles.clone();

        let mut area_share_mm2 = vec![0.0f32; n];
        let mut normal_sum = vec![Vec3::zeros(); n];
        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(triangles.len() * 3);
        for tri in &triangles {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            let area_normal = 0.5 * (b - a).cross(&(c - a));
            let area = area_normal.norm();
            for k in 0..3 {
                normal_sum[tri[k] as usize] += area_normal;
                area_share_mm2[tri[k] as usize] += area / 3.0;
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                edges.push([p.min(q), p.max(q)]);
            }
        }
        edges.sort_unstable();
        edges.dedup();

        let total_area: f32 = area_share_mm2.iter().sum();
        let mass_kg: Vec<f32> = match spec.material.mass {
            MassSpec::TotalKg(total) => area_share_mm2
                .iter()
                .map(|a| total * a / total_area)
                .collect(),
            MassSpec::Density {
                kg_per_m3,
                thickness_mm,
            } => area_share_mm2
                .iter()
                .map(|a| a * thickness_mm * kg_per_m3 * 1e-9)
                .collect(),
        };
        let fixed: Vec<bool> = spec
            .mesh
            .positions_mm
            .iter()
            .map(|p| spec.fixed.iter().any(|s| s.contains(*p)))
            .collect();
        let accel_per_force = mass_kg
            .iter()
            .zip(&fixed)
            .map(|(m, &f)| if f || *m <= 0.0 { 0.0 } else { MM_PER_M / m })
            .collect();
        let springs = edges
            .iter()
            .map(|&[a, b]| Spring {
                a,
                b,
                rest_length_mm: (positions[b as usize] - positions[a as usize]).norm(),
                stiffness_n_per_mm: spec.material.stiffness_n_per_mm,
                damping_n_s_per_mm: spec.material.damping_n_s_per_mm,
            })
            .collect();

        let mut degree = vec![0u32; n + 1];
        for [a, b] in &edges {
            degree[*a as usize + 1] += 1;
            degree[*b as usize + 1] += 1;
        }
        for i in 0..n {
            degree[i + 1] += degree[i];
        }
        let node_edge_start = degree;
        let mut fill = node_edge_start.clone();
        let mut node_edges = vec![0u32; edges.len() * 2];
        for (e, [a, b]) in edges.iter().enumerate() {
            for v in [a, b] {
                node_edges[fill[*v as usize] as usize] = e as u32;
                fill[*v as usize] += 1;
            }
        }

        let rest_normals = normal_sum
            .iter()
            .map(|s| s.try_normalize(1e-12).unwrap_or_else(Vec3::z))
            .collect();
        Self {
            rest_positions_mm: positions,
            rest_normals,
            mass_kg,
            accel_per_force,
            springs,
            anchor_stiffness_n_per_mm: spec.material.anchor_stiffness_n_per_mm,
            drag_per_s: spec.material.drag_per_s,
            triangles,
            node_edge_start,
            node_edges,
        }
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

    /// Outward unit normal at each node at rest (area-weighted, from the triangle winding).
    pub fn rest_normals(&self) -> &[Vec3] {
        &self.rest_normals
    }

    /// Surface triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
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

    /// Internal force on every node (springs, edge dampers, anchors), N, written into `forces_n`.
    /// Real-time contract: no allocation, never panics (a zero-length edge contributes nothing).
    pub fn compute_forces(
        &self,
        positions_mm: &[Vec3],
        velocities_mm_s: &[Vec3],
        forces_n: &mut [Vec3],
    ) {
        let k_anchor = self.anchor_stiffness_n_per_mm;
        for ((f, x), rest) in forces_n
            .iter_mut()
            .zip(positions_mm)
            .zip(&self.rest_positions_mm)
        {
            *f = (rest - x) * k_anchor;
        }
        // Springs are sorted by their first node: accumulate that node's share in a register and store it
        // once per node, instead of a load-add-store chain through memory on every spring.
        let mut current = usize::MAX;
        let mut on_current = Vec3::zeros();
        for spring in &self.springs {
            let (a, b) = (spring.a as usize, spring.b as usize);
            if a != current {
                if let Some(f) = forces_n.get_mut(current) {
                    *f += on_current;
                }
                current = a;
                on_current = Vec3::zeros();
            }
            let f = spring.force_on_a(positions_mm, velocities_mm_s);
            on_current += f;
            forces_n[b] -= f;
        }
        if let Some(f) = forces_n.get_mut(current) {
            *f += on_current;
        }
    }

    /// Internal force on node `i` alone (its incident edges and anchor), N. No allocation.
    pub fn node_force(&self, i: usize, positions_mm: &[Vec3], velocities_mm_s: &[Vec3]) -> Vec3 {
        let mut f = (self.rest_positions_mm[i] - positions_mm[i]) * self.anchor_stiffness_n_per_mm;
        let span = self.node_edge_start[i] as usize..self.node_edge_start[i + 1] as usize;
        for &e in &self.node_edges[span] {
            let spring = &self.springs[e as usize];
            let on_a = spring.force_on_a(positions_mm, velocities_mm_s);
            f += if spring.a as usize == i { on_a } else { -on_a };
        }
        f
    }

    /// A conservative bound on the largest stable step for explicit/symplectic Euler, seconds.
    ///
    /// Per free node, Gershgorin bounds the largest eigenvalue of the stiffness matrix by
    /// `K = 2 * sum(k_edge) + k_anchor` and of the damping matrix by `C = 2 * sum(c_edge)`; with
    /// `w^2 = 1000 K / m` and `g = 1000 C / m`, symplectic Euler is stable while `h^2 w^2 + 2 h g < 4`,
    /// i.e. `h < (-g + sqrt(g^2 + 4 w^2)) / w^2`. Drag is integrated implicitly and does not limit the step.
    pub fn stable_dt_bound_s(&self) -> f32 {
        let mut bound = f32::INFINITY;
        for i in 0..self.node_count() {
            let w = self.accel_per_force[i];
            if w == 0.0 {
                continue;
            }
            let span = self.node_edge_start[i] as usize..self.node_edge_start[i + 1] as usize;
            let (mut k, mut c) = (self.anchor_stiffness_n_per_mm, 0.0);
            for &e in &self.node_edges[span] {
                k += 2.0 * self.springs[e as usize].stiffness_n_per_mm;
                c += 2.0 * self.springs[e as usize].damping_n_s_per_mm;
            }
            let omega2 = w * k;
            let gamma = w * c;
            if omega2 > 0.0 {
                let h = (-gamma + (gamma * gamma + 4.0 * omega2).sqrt()) / omega2;
                bound = bound.min(h);
            } else if gamma > 0.0 {
                bound = bound.min(2.0 / gamma);
            }
        }
        bound
    }
}

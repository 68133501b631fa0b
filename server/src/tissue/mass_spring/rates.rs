//! The model's stiffness and damping rates per node at rest, bounded by Gershgorin: what the stability
//! analysis turns into a largest stable step.
//!
//! Owns: [`MassSpringModel::node_rates`]. Must not: compute forces or decide a step (the stability
//! analysis does, from these rates).

use super::*;

impl MassSpringModel {
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
            let (k, c) = self.node_bounds(i, stiffening);
            let k = k + self.global_volume.as_ref().map_or(0.0, |global| {
                global.bulk_modulus_n_per_mm2 / global.rest_volume_mm3
                    * global_gradient_norm(i)
                    * global_row
            });
            Some((w * k, w * c))
        })
    }

    /// Node `i`'s Gershgorin bounds `(K, C)` (N/mm, N s/mm) without the global volume term: its springs
    /// (`2 k stiffening` each), the anchor, its tetrahedra's volume terms and finite elements at rest, and
    /// `2 sum(c)` of its springs' damping. See [`Self::node_rates`].
    pub fn node_bounds(&self, i: usize, stiffening: f32) -> (f32, f32) {
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
                let g = crate::tissue::volume::tet_volume_gradients(x, tet);
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
        (k, c)
    }
}

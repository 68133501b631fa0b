//! Volume preservation: a global term for closed surfaces and a local term per tetrahedron.
//!
//! Both use the same energy, `E = K (V - V0)^2 / (2 V0)` with `K` a bulk modulus in N/mm^2 (1 kPa = 1e-3
//! N/mm^2), whose force on a vertex is `-K (V - V0) / V0 * dV/dx`: a pressure along the area-weighted vertex
//! normal for a closed surface, and along the opposite face normals for a tetrahedron. Real-time contract: no
//! allocation, never panics.

use super::Vec3;

/// Signed volume enclosed by a closed, outward-wound triangle surface, mm^3 (divergence theorem).
pub fn enclosed_volume_mm3(positions_mm: &[Vec3], triangles: &[[u32; 3]]) -> f32 {
    let mut six_v = 0.0f32;
    for t in triangles {
        let [a, b, c] = t.map(|i| positions_mm[i as usize]);
        six_v += a.dot(&b.cross(&c));
    }
    six_v / 6.0
}

/// Global volume preservation of a closed surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlobalVolume {
    /// Volume at rest, mm^3.
    pub rest_volume_mm3: f32,
    /// Bulk modulus, N/mm^2.
    pub bulk_modulus_n_per_mm2: f32,
}

impl GlobalVolume {
    /// Pressure the surface feels at these positions, N/mm^2 (positive pushes outward).
    pub fn pressure_n_per_mm2(&self, positions_mm: &[Vec3], triangles: &[[u32; 3]]) -> f32 {
        let volume = enclosed_volume_mm3(positions_mm, triangles);
        -self.bulk_modulus_n_per_mm2 * (volume - self.rest_volume_mm3) / self.rest_volume_mm3
    }

    /// Add the pressure force on every surface vertex to `forces_n`; returns the pressure, N/mm^2.
    pub fn accumulate_forces(
        &self,
        positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
        forces_n: &mut [Vec3],
    ) -> f32 {
        let pressure = self.pressure_n_per_mm2(positions_mm, triangles);
        let scale = pressure / 6.0;
        for t in triangles {
            let [a, b, c] = t.map(|i| positions_mm[i as usize]);
            forces_n[t[0] as usize] += b.cross(&c) * scale;
            forces_n[t[1] as usize] += c.cross(&a) * scale;
            forces_n[t[2] as usize] += a.cross(&b) * scale;
        }
        pressure
    }

    /// The pressure force on one vertex given the pressure, using its incident triangles. No allocation.
    pub fn vertex_force(
        pressure_n_per_mm2: f32,
        vertex: usize,
        incident: &[u32],
        positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
    ) -> Vec3 {
        let mut grad = Vec3::zeros();
        for &t in incident {
            let tri = triangles[t as usize];
            let k = tri.iter().position(|&v| v as usize == vertex).unwrap_or(0);
            let (b, c) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            grad += positions_mm[b as usize].cross(&positions_mm[c as usize]);
        }
        grad * (pressure_n_per_mm2 / 6.0)
    }
}

/// Signed volume of a tetrahedron (positive when `d` is on the side `(b - a) x (c - a)` points to), mm^3.
#[inline(always)]
pub fn tet_volume_mm3(x: &[Vec3], tet: [u32; 4]) -> f32 {
    let [a, b, c, d] = tet.map(|i| x[i as usize]);
    (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
}

/// A tetrahedron's shape quality, `6 sqrt(2) V / l_rms^3` (`V` signed, `l_rms` the root mean square of its six
/// edges): 1 for a regular tetrahedron, 0 for a flat one, negative for one turned over. Dimensionless.
pub fn tet_shape_quality(x: &[Vec3], tet: [u32; 4]) -> f32 {
    let p = tet.map(|v| x[v as usize]);
    let mut sum = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            sum += (p[i] - p[j]).norm_squared();
        }
    }
    let l_rms = (sum / 6.0).sqrt();
    6.0 * 2f32.sqrt() * tet_volume_mm3(x, tet) / (l_rms * l_rms * l_rms)
}

/// Gradients of a tetrahedron's volume with respect to its four vertices, mm^2.
#[inline(always)]
pub fn tet_volume_gradients(x: &[Vec3], tet: [u32; 4]) -> [Vec3; 4] {
    let [a, b, c, d] = tet.map(|i| x[i as usize]);
    let gb = (c - a).cross(&(d - a)) / 6.0;
    let gc = (d - a).cross(&(b - a)) / 6.0;
    let gd = (b - a).cross(&(c - a)) / 6.0;
    [-(gb + gc + gd), gb, gc, gd]
}

/// Local volume preservation: one volume term per tetrahedron.
#[derive(Debug, Clone, Default)]
pub struct TetVolumes {
    /// Vertex indices, positively oriented at rest.
    pub tets: Vec<[u32; 4]>,
    /// Rest volume of each, mm^3 (positive).
    pub rest_volume_mm3: Vec<f32>,
    /// Bulk modulus, N/mm^2.
    pub bulk_modulus_n_per_mm2: f32,
}

impl TetVolumes {
    /// Tetrahedra with rest volumes measured at `rest_positions_mm`; inverted ones are reoriented, and
    /// degenerate ones (volume below `1e-9` mm^3) dropped. Returns the terms and the number dropped.
    pub fn new(
        tets: &[[u32; 4]],
        rest_positions_mm: &[Vec3],
        bulk_modulus_n_per_mm2: f32,
    ) -> (Self, usize) {
        let mut out = Self::default();
        let dropped = out.refill(tets, rest_positions_mm, bulk_modulus_n_per_mm2);
        (out, dropped)
    }

    /// [`Self::new`] into this value's buffers; returns the number dropped.
    pub fn refill(
        &mut self,
        tets: &[[u32; 4]],
        rest_positions_mm: &[Vec3],
        bulk_modulus_n_per_mm2: f32,
    ) -> usize {
        self.tets.clear();
        self.rest_volume_mm3.clear();
        self.bulk_modulus_n_per_mm2 = bulk_modulus_n_per_mm2;
        let mut dropped = 0;
        for &tet in tets {
            let mut tet = tet;
            let mut v = tet_volume_mm3(rest_positions_mm, tet);
            if v < 0.0 {
                tet.swap(2, 3);
                v = -v;
            }
            if v > 1e-9 {
                self.tets.push(tet);
                self.rest_volume_mm3.push(v);
            } else {
                dropped += 1;
            }
        }
        dropped
    }

    /// Number of tetrahedra.
    pub fn len(&self) -> usize {
        self.tets.len()
    }

    /// No tetrahedra.
    pub fn is_empty(&self) -> bool {
        self.tets.is_empty()
    }

    /// Force of tetrahedron `t` on its four vertices, N.
    #[inline(always)]
    pub fn forces(&self, t: usize, x: &[Vec3]) -> [Vec3; 4] {
        let tet = self.tets[t];
        let v0 = self.rest_volume_mm3[t];
        let scale = -self.bulk_modulus_n_per_mm2 * (tet_volume_mm3(x, tet) - v0) / v0;
        tet_volume_gradients(x, tet).map(|g| g * scale)
    }

    /// Add every tetrahedron's volume force to `forces_n`.
    pub fn accumulate_forces(&self, x: &[Vec3], forces_n: &mut [Vec3]) {
        if self.bulk_modulus_n_per_mm2 == 0.0 {
            return;
        }
        for t in 0..self.len() {
            let f = self.forces(t, x);
            for (k, &v) in self.tets[t].iter().enumerate() {
                forces_n[v as usize] += f[k];
            }
        }
    }
}

impl TetVolumes {
    /// Each tetrahedron's volume gradients at `x` into `out` (empty when the term is off): the frozen
    /// linearisation [`Self::add_stiffness_product`] uses.
    pub fn gradients_into(&self, x: &[Vec3], out: &mut Vec<[Vec3; 4]>) {
        out.clear();
        if self.bulk_modulus_n_per_mm2 == 0.0 {
            return;
        }
        out.extend(self.tets.iter().map(|&tet| tet_volume_gradients(x, tet)));
    }

    /// `out += scale K p` with `K = sum_t K_bulk / V0 g_t g_t^T` (the term's Gauss-Newton stiffness, gradients
    /// from [`Self::gradients_into`]).
    pub fn add_stiffness_product(
        &self,
        gradients: &[[Vec3; 4]],
        p: &[Vec3],
        scale: f32,
        out: &mut [Vec3],
    ) {
        if gradients.len() != self.tets.len() {
            return;
        }
        for ((tet, g), &v0) in self.tets.iter().zip(gradients).zip(&self.rest_volume_mm3) {
            let along: f32 = (0..4).map(|k| g[k].dot(&p[tet[k] as usize])).sum();
            let w = along * self.bulk_modulus_n_per_mm2 / v0 * scale;
            for k in 0..4 {
                out[tet[k] as usize] += g[k] * w;
            }
        }
    }

    /// `diagonal += scale diag(K)` per axis for the same `K`.
    pub fn add_stiffness_diagonal(
        &self,
        gradients: &[[Vec3; 4]],
        scale: f32,
        diagonal: &mut [Vec3],
    ) {
        if gradients.len() != self.tets.len() {
            return;
        }
        for ((tet, g), &v0) in self.tets.iter().zip(gradients).zip(&self.rest_volume_mm3) {
            let w = self.bulk_modulus_n_per_mm2 / v0 * scale;
            for k in 0..4 {
                diagonal[tet[k] as usize] += g[k].component_mul(&g[k]) * w;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        // Outward-wound faces (two triangles each).
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let tris = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (p, tris)
    }

    #[test]
    fn cube_volume_and_pressure_gradient_match_finite_differences() {
        let (mut p, tris) = unit_cube();
        assert!((enclosed_volume_mm3(&p, &tris) - 1.0).abs() < 1e-6);
        let global = GlobalVolume {
            rest_volume_mm3: 1.0,
            bulk_modulus_n_per_mm2: 2.0,
        };
        p[7] += Vec3::new(0.1, 0.05, -0.02);
        let mut f = vec![Vec3::zeros(); 8];
        let pressure = global.accumulate_forces(&p, &tris, &mut f);
        // Force = -dE/dx by central differences on E = K (V - V0)^2 / (2 V0).
        let energy = |p: &[Vec3]| {
            let v = enclosed_volume_mm3(p, &tris);
            2.0 * (v - 1.0) * (v - 1.0) / 2.0
        };
        for axis in 0..3 {
            let (mut plus, mut minus) = (p.clone(), p.clone());
            plus[7][axis] += 1e-3;
            minus[7][axis] -= 1e-3;
            let numeric = -(energy(&plus) - energy(&minus)) / 2e-3;
            assert!(
                (f[7][axis] - numeric).abs() < 2e-3,
                "axis {axis}: {} vs {numeric}",
                f[7][axis]
            );
        }
        let incident: Vec<u32> = (0..tris.len() as u32)
            .filter(|&t| tris[t as usize].contains(&7))
            .collect();
        let one = GlobalVolume::vertex_force(pressure, 7, &incident, &p, &tris);
        assert!((one - f[7]).norm() < 1e-6);
    }

    #[test]
    fn tet_force_restores_volume_and_sums_to_zero() {
        let x = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        let (tets, dropped) = TetVolumes::new(&[[0, 1, 2, 3], [0, 1, 2, 2]], &x, 1.0);
        assert_eq!((tets.len(), dropped), (1, 1));
        let mut squeezed = x.clone();
        squeezed[3].z = 0.5;
        let f = tets.forces(0, &squeezed);
        assert!(f[3].z > 0.0, "a squeezed tet pushes its apex back out");
        let total: Vec3 = f.iter().sum();
        assert!(total.norm() < 1e-6);
    }
}

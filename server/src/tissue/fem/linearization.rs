//! The linearisation the implicit integrator solves with: each element's rotation and volume gradients
//! frozen at one state, and the products and diagonal of the stiffness they make.
//!
//! Owns: [`FemElements::linearize`], the stiffness product `K p` (deviatoric and nodal-volume parts), its
//! Jacobi diagonal, and [`element_deviatoric_product`], the one-element product the contact model also
//! applies. Must not: compute forces (that is `forces`) or keep any state beyond the
//! [`FemLinearization`] it is handed.

use super::*;

impl FemElements {
    /// Freeze each element's rotation and volume gradients at `x` into `lin` (the corotational stiffness
    /// `R K0 R^T` and the Gauss-Newton nodal-volume term the implicit integrator solves with).
    pub fn linearize(&self, tets: &TetVolumes, x: &[Vec3], lin: &mut FemLinearization) {
        lin.clear(self.node_rest_volume_mm3.len());
        if !self.is_on() {
            return;
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            lin.rotations.push(self.rotation(t, tet, x));
            lin.gradients.push(tet_volume_gradients(x, tet));
        }
    }

    /// `out += scale K p` with `K` the stiffness frozen in `lin` (made by [`Self::linearize`] on this model).
    pub fn add_stiffness_product(
        &self,
        tets: &TetVolumes,
        lin: &mut FemLinearization,
        p: &[Vec3],
        scale: f32,
        out: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            let v0 = tets.rest_volume_mm3[t] * scale;
            let y = self.deviatoric_product(t, &lin.rotations[t], &tet.map(|i| p[i as usize]), v0);
            for (k, &i) in tet.iter().enumerate() {
                out[i as usize] += y[k];
            }
        }
        self.add_volume_product(tets, lin, p, scale, out);
    }

    /// `out += scale K_vol p`: the nodal volume term's part of [`Self::add_stiffness_product`] alone (the
    /// deviatoric part may come assembled instead: [`crate::tissue::fem_assembly`]).
    pub fn add_volume_product(
        &self,
        tets: &TetVolumes,
        lin: &mut FemLinearization,
        p: &[Vec3],
        scale: f32,
        out: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        // Nodal volumes: K_vol p = sum_a kappa / V_a0 g_a (g_a . p), g_a = sum_{t around a} dV_t/dx / 4.
        lin.node_sum.iter_mut().for_each(|s| *s = 0.0);
        for (t, &tet) in tets.tets.iter().enumerate() {
            let g = &lin.gradients[t];
            let q: f32 = (0..4).map(|k| g[k].dot(&p[tet[k] as usize])).sum::<f32>() / 4.0;
            for &a in &tet {
                lin.node_sum[a as usize] += q;
            }
        }
        for (s, &v0) in lin.node_sum.iter_mut().zip(&self.node_rest_volume_mm3) {
            *s = if v0 > 0.0 {
                *s * self.bulk_n_per_mm2 / v0
            } else {
                0.0
            };
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            let g = &lin.gradients[t];
            let w: f32 = tet.iter().map(|&a| lin.node_sum[a as usize]).sum::<f32>() * (scale / 4.0);
            for k in 0..4 {
                out[tet[k] as usize] += g[k] * w;
            }
        }
    }

    /// Element `t`'s deviatoric stiffness (its rotation `r` frozen, rest volume `v0_mm3`) times its four
    /// nodes' displacements `p`: the element's part of `K p`, N per node.
    #[inline(always)]
    fn deviatoric_product(
        &self,
        t: usize,
        r: &Matrix3<f32>,
        p: &[Vec3; 4],
        v0_mm3: f32,
    ) -> [Vec3; 4] {
        element_deviatoric_product(
            &self.rest_inverse[t],
            r,
            p,
            2.0 * self.shear_n_per_mm2 * v0_mm3,
        )
    }

    /// `diagonal += scale diag(K)` per axis, K frozen in `lin`: each element's rotated deviatoric block
    /// diagonal and the per-element bound of the volume term (a Jacobi preconditioner's estimate).
    pub fn add_stiffness_diagonal(
        &self,
        tets: &TetVolumes,
        lin: &FemLinearization,
        scale: f32,
        diagonal: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        let mu = self.shear_n_per_mm2;
        for (t, &tet) in tets.tets.iter().enumerate() {
            let inverse = &self.rest_inverse[t];
            let v0 = tets.rest_volume_mm3[t];
            for (k, &i) in tet.iter().enumerate() {
                let b = lin.rotations[t] * shape_gradient(inverse, k);
                let g = lin.gradients[t][k];
                let b2 = b.norm_squared();
                let d = b.map(|c| mu * v0 * (b2 + c * c / 3.0))
                    + g.map(|c| self.bulk_n_per_mm2 / v0 * c * c);
                diagonal[i as usize] += d * scale;
            }
        }
    }
}

/// One element's deviatoric stiffness times its four nodes' displacements `p`: the element's part of `K p`,
/// N per node, with `inverse` its `Dm^-1`, `r` its frozen rotation and `two_mu_v0` = 2 mu V0 (N mm). The
/// local contact model ([`crate::haptics::contact_stiffness`]) applies it element by element.
#[inline(always)]
pub fn element_deviatoric_product(
    inverse: &Matrix3<f32>,
    r: &Matrix3<f32>,
    p: &[Vec3; 4],
    two_mu_v0: f32,
) -> [Vec3; 4] {
    let dp = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * inverse;
    let stress = deviatoric_strain_increment(&(r.transpose() * dp));
    // K p = -df: the element's force change, negated.
    let h = (r * stress * inverse.transpose()) * two_mu_v0;
    let (f1, f2, f3) = (
        h.column(0).into_owned(),
        h.column(1).into_owned(),
        h.column(2).into_owned(),
    );
    [-(f1 + f2 + f3), f1, f2, f3]
}

/// `sym(m)` with its trace removed (a strain increment: no identity to subtract).
#[inline(always)]
fn deviatoric_strain_increment(m: &Matrix3<f32>) -> Matrix3<f32> {
    let e = (m + m.transpose()) * 0.5;
    let mean = e.trace() / 3.0;
    e - Matrix3::from_diagonal_element(mean)
}

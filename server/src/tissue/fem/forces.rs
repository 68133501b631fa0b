//! The elements' force pass and their elastic energy.
//!
//! Owns: each element's deviatoric force, the nodal pressures of the volume term, the whole force pass
//! ([`FemElements::accumulate_forces`], which can freeze the linearisation on the way), one node's force
//! alone, and the energy. Must not: build the rest data (the parent does) or solve anything (the
//! linearisation's products are in `linearization`).

use super::*;
use crate::tissue::volume::tet_volume_mm3;

/// `sym(m) - I` with its trace removed: the deviatoric small strain of a rotated gradient `m`.
#[inline(always)]
fn deviatoric_strain(m: &Matrix3<f32>) -> Matrix3<f32> {
    let e = (m + m.transpose()) * 0.5 - Matrix3::identity();
    let mean = e.trace() / 3.0;
    e - Matrix3::from_diagonal_element(mean)
}

impl FemElements {
    /// Deviatoric force of element `t` on its four nodes, N, and the element's rotation.
    #[inline(always)]
    fn deviatoric_forces(
        &self,
        t: usize,
        tet: [u32; 4],
        v0: f32,
        x: &[Vec3],
    ) -> ([Vec3; 4], Matrix3<f32>) {
        let inverse = &self.rest_inverse[t];
        let f = edge_matrix(tet, x) * inverse;
        let r = if self.material.is_some_and(|m| m.corotated) {
            rotation_of(&f)
        } else {
            Matrix3::identity()
        };
        let stress = deviatoric_strain(&(r.transpose() * f)) * (2.0 * self.shear_n_per_mm2);
        let h = -(r * stress * inverse.transpose()) * v0;
        let (f1, f2, f3) = (
            h.column(0).into_owned(),
            h.column(1).into_owned(),
            h.column(2).into_owned(),
        );
        ([-(f1 + f2 + f3), f1, f2, f3], r)
    }

    /// Add every element's force at `x` to `forces_n`; with `lin`, also freeze the elements' rotations and
    /// volume gradients there, as [`Self::linearize`] does (one polar decomposition per element for both).
    pub fn accumulate_forces(
        &self,
        tets: &TetVolumes,
        x: &[Vec3],
        forces_n: &mut [Vec3],
        mut lin: Option<&mut FemLinearization>,
    ) {
        if let Some(lin) = lin.as_deref_mut() {
            lin.clear(self.node_rest_volume_mm3.len());
        }
        if !self.is_on() {
            return;
        }
        self.scratch
            .with(|scratch| self.accumulate_with(tets, x, forces_n, lin, scratch));
    }

    fn accumulate_with(
        &self,
        tets: &TetVolumes,
        x: &[Vec3],
        forces_n: &mut [Vec3],
        mut lin: Option<&mut FemLinearization>,
        scratch: &mut FemScratch,
    ) {
        self.node_pressures(tets, x, scratch);
        for (t, &tet) in tets.tets.iter().enumerate() {
            let v0 = tets.rest_volume_mm3[t];
            let (deviatoric, rotation) = self.deviatoric_forces(t, tet, v0, x);
            let gradients = tet_volume_gradients(x, tet);
            if let Some(lin) = lin.as_deref_mut() {
                lin.rotations.push(rotation);
                lin.gradients.push(gradients);
            }
            let mean_pressure = tet
                .iter()
                .map(|&i| scratch.node_pressure_n_per_mm2[i as usize])
                .sum::<f32>()
                / 4.0;
            for (k, &i) in tet.iter().enumerate() {
                forces_n[i as usize] += deviatoric[k] + gradients[k] * mean_pressure;
            }
        }
    }

    /// Every node's volume and pressure `-kappa (V_a - V_a0) / V_a0` at `x` into `scratch`.
    fn node_pressures(&self, tets: &TetVolumes, x: &[Vec3], scratch: &mut FemScratch) {
        let n = self.node_rest_volume_mm3.len();
        scratch.node_volume_mm3.clear();
        scratch.node_volume_mm3.resize(n, 0.0);
        for &tet in &tets.tets {
            let quarter = tet_volume_mm3(x, tet) / 4.0;
            for &i in &tet {
                scratch.node_volume_mm3[i as usize] += quarter;
            }
        }
        scratch.node_pressure_n_per_mm2.clear();
        scratch.node_pressure_n_per_mm2.extend(
            scratch
                .node_volume_mm3
                .iter()
                .zip(&self.node_rest_volume_mm3)
                .map(|(&v, &v0)| {
                    if v0 > 0.0 {
                        -self.bulk_n_per_mm2 * (v - v0) / v0
                    } else {
                        0.0
                    }
                }),
        );
    }

    /// Pressure of node `a` at `x` from its own tetrahedra (`node_tets.of(a)`), N/mm^2. No allocation.
    fn node_pressure(
        &self,
        a: usize,
        tets: &TetVolumes,
        node_tets: NodeTets<'_>,
        x: &[Vec3],
    ) -> f32 {
        let v0 = self.node_rest_volume_mm3[a];
        if v0 <= 0.0 {
            return 0.0;
        }
        let v: f32 = node_tets
            .of(a)
            .iter()
            .map(|&t| tet_volume_mm3(x, tets.tets[t as usize]) / 4.0)
            .sum();
        -self.bulk_n_per_mm2 * (v - v0) / v0
    }

    /// Elastic force on node `i` alone at `x`, N: its elements' deviatoric forces and the nodal pressures
    /// of their nodes (two rings of tetrahedra). No allocation.
    pub fn node_force(
        &self,
        i: usize,
        tets: &TetVolumes,
        node_tets: NodeTets<'_>,
        x: &[Vec3],
    ) -> Vec3 {
        let mut force = Vec3::zeros();
        if !self.is_on() {
            return force;
        }
        for &t in node_tets.of(i) {
            let t = t as usize;
            let tet = tets.tets[t];
            let Some(k) = tet.iter().position(|&v| v as usize == i) else {
                continue;
            };
            force += self.deviatoric_forces(t, tet, tets.rest_volume_mm3[t], x).0[k];
            let mean_pressure = tet
                .iter()
                .map(|&a| self.node_pressure(a as usize, tets, node_tets, x))
                .sum::<f32>()
                / 4.0;
            force += tet_volume_gradients(x, tet)[k] * mean_pressure;
        }
        force
    }

    /// Elastic energy at `x`, N mm: `mu V0 |dev e|^2` per element plus `kappa (V_a - V_a0)^2 / (2 V_a0)` per
    /// node.
    pub fn energy_n_mm(&self, tets: &TetVolumes, x: &[Vec3]) -> f64 {
        if !self.is_on() {
            return 0.0;
        }
        let mut total = 0.0f64;
        for (t, &tet) in tets.tets.iter().enumerate() {
            let f = edge_matrix(tet, x) * self.rest_inverse[t];
            let r = self.rotation(t, tet, x);
            let e = deviatoric_strain(&(r.transpose() * f));
            total += f64::from(self.shear_n_per_mm2 * tets.rest_volume_mm3[t] * e.norm_squared());
        }
        self.scratch.with(|scratch| {
            self.node_pressures(tets, x, scratch);
            for (&v, &v0) in scratch
                .node_volume_mm3
                .iter()
                .zip(&self.node_rest_volume_mm3)
            {
                if v0 > 0.0 {
                    total += f64::from(0.5 * self.bulk_n_per_mm2 * (v - v0) * (v - v0) / v0);
                }
            }
        });
        total
    }
}

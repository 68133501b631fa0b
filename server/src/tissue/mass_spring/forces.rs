//! The model's forces and energy at given positions: the whole force pass every integrator calls, one
//! node's force alone, the elastic energy and the global-volume pressure.
//!
//! Owns: how the spring kernel, the per-tetrahedron and global volume terms and the finite elements add
//! up to one force per node. Must not: keep state between calls (the kernel's scratch is scratch) or
//! move a node.

use super::*;
use crate::tissue::MM_PER_M;
use crate::tissue::fem::FemLinearization;
use crate::tissue::springs::{ForcePass, NodeSprings};

impl MassSpringModel {
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
                let dv = crate::tissue::volume::tet_volume_mm3(positions_mm, tets.tets[t]) - v0;
                total += f64::from(0.5 * tets.bulk_modulus_n_per_mm2 * dv * dv / v0);
            }
        }
        if let Some(global) = &self.global_volume {
            let dv = crate::tissue::volume::enclosed_volume_mm3(positions_mm, &self.triangles)
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
}

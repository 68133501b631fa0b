//! Setting up one solve: the local problem around the held nodes, its tangent blocks and volume terms at
//! the current state, the Jacobi preconditioner and the right-hand sides.
//!
//! Owns: which nodes are held, free or still, the rings of free nodes, the springs' tangent blocks, the
//! tetrahedra touching the set, and the nodal-volume slots. Must not: iterate (that is `solve`) or
//! write the tissue's state.

use super::*;
use crate::tissue::springs::{spring_tangent, sym_block};
use crate::tissue::volume::tet_volume_gradients;

impl ContactStiffness {
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
    pub(super) fn set_up(
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

        // Held nodes first, with their imposed motion for each solved direction: a push solves only the
        // contact normal's mode (see the module doc; the other two stay zero); a grasp holds its points in
        // every direction, so the tool's three axes are solved (the full 3x3 `K`).
        self.full = !grasped.is_empty();
        let axes = if self.full {
            [Vec3::x(), Vec3::y(), Vec3::z()]
        } else {
            [*contact_normal, Vec3::zeros(), Vec3::zeros()]
        };
        let push_dirs = model.rest_normals();
        for (&g, normal) in held.iter().zip(tool_normals) {
            let g = g as usize;
            if g >= n || self.local_of[g] != NONE || !self.local(g, HELD, model) {
                continue;
            }
            let d = -push_dirs[g];
            let along = normal.dot(&d);
            for (u, axis) in self.u.iter_mut().zip(&axes) {
                u.push(if along.abs() > 0.2 {
                    d * (normal.dot(axis) / along)
                } else {
                    Vec3::zeros()
                });
            }
        }
        // Grasped nodes move rigidly with the jaws: all of the tool's motion is imposed on them.
        for &g in grasped {
            let g = g as usize;
            if g >= n || self.local_of[g] != NONE || !self.local(g, HELD, model) {
                continue;
            }
            for (u, axis) in self.u.iter_mut().zip(&axes) {
                u.push(*axis);
            }
        }
        // Rings of free nodes around them (breadth first over the spring graph).
        let mut ring_start = 0;
        for _ in 0..self.rings {
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
        // A warm start: the last solve's free displacements, when it covered this same set (the tolerance
        // stays relative to b).
        if self.warm_start
            && self.warm_full == self.full
            && self.warm_nodes.len() == m
            && self.warm_nodes == self.nodes
        {
            self.start_from_last_solve();
        }
        self.iterations = 0;
        self.solving = true;
    }

    /// `u_F <- u_F(last)`, `r <- b - A_FF u_F`, `p <- M^-1 r`, per unconverged direction. No allocation.
    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    fn start_from_last_solve(&mut self) {
        let m = self.nodes.len();
        for dir in 0..3 {
            if self.converged[dir] {
                continue;
            }
            // The free part alone, in p (scratch until it is set below).
            let mut free = std::mem::take(&mut self.p[dir]);
            for l in 0..m {
                free[l] = if self.role[l] == FREE {
                    self.warm_u[dir][l]
                } else {
                    Vec3::zeros()
                };
            }
            let mut a_free = std::mem::take(&mut self.ap[dir]);
            self.apply(&free, &mut a_free);
            let mut rz = 0.0;
            for l in 0..m {
                if self.role[l] != FREE {
                    continue;
                }
                self.u[dir][l] = free[l];
                self.r[dir][l] -= a_free[l];
                let z = self.precondition(l, &self.r[dir][l]);
                free[l] = z;
                rz += self.r[dir][l].dot(&z);
            }
            for l in 0..m {
                if self.role[l] != FREE {
                    free[l] = Vec3::zeros();
                }
            }
            self.p[dir] = free;
            self.ap[dir] = a_free;
            self.rz[dir] = rz;
        }
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
}

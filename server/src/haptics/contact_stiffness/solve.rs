//! The solve: the product with the local tangent stiffness `A`, the Jacobi preconditioner, the conjugate
//! gradient iterations over the three right-hand sides, and the normal mode's stiffness and damping.
//!
//! Owns: `A v` (springs, anchors, volume terms), one CG iteration, and turning a converged (or given up)
//! solve into a [`ContactResponse`]. Must not: change the local problem (`local_problem` sets it up)
//! or allocate.

use super::*;
use crate::tissue::fem::element_deviatoric_product;
use crate::tissue::springs::sym_block_mul;

impl ContactStiffness {
    /// `out += A_vol v`: the volume terms' part of the product.
    fn apply_volume(&self, v: &[Vec3], out: &mut [Vec3]) {
        let at = |l: u32| {
            if l == NONE {
                Vec3::zeros()
            } else {
                v[l as usize]
            }
        };
        match self.volume_terms {
            VolumeTerms::Off => {}
            VolumeTerms::PerTet => {
                for lt in &self.tets {
                    let q: f32 = (0..4).map(|k| lt.gradients[k].dot(&at(lt.local[k]))).sum();
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += lt.gradients[k] * (q * lt.modulus);
                        }
                    }
                }
            }
            VolumeTerms::Fem => {
                let mut sums = self.pressure_sum.borrow_mut();
                sums.iter_mut().for_each(|s| *s = 0.0);
                for lt in &self.tets {
                    let p = lt.local.map(at);
                    let y =
                        element_deviatoric_product(&lt.rest_inverse, &lt.rotation, &p, lt.modulus);
                    let mut q = 0.0;
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += y[k];
                        }
                        q += lt.gradients[k].dot(&p[k]);
                    }
                    for &slot in &lt.pressure {
                        if let Some(s) = sums.get_mut(slot as usize) {
                            *s += q / 4.0;
                        }
                    }
                }
                for (s, &k) in sums.iter_mut().zip(&self.pressure_modulus) {
                    *s *= k;
                }
                for lt in &self.tets {
                    let w: f32 = lt
                        .pressure
                        .iter()
                        .filter_map(|&slot| sums.get(slot as usize))
                        .sum::<f32>()
                        / 4.0;
                    for (k, &l) in lt.local.iter().enumerate() {
                        if l != NONE {
                            out[l as usize] += lt.gradients[k] * w;
                        }
                    }
                }
            }
        }
    }

    pub(super) fn precondition(&self, l: usize, r: &Vec3) -> Vec3 {
        if self.role[l] != FREE {
            return Vec3::zeros();
        }
        let d = self.diag[l];
        Vec3::new(
            r.x / d.x.max(1e-9),
            r.y / d.y.max(1e-9),
            r.z / d.z.max(1e-9),
        )
    }

    /// `out = A v` over the local set (outside ends count as still).
    pub(super) fn apply(&self, v: &[Vec3], out: &mut [Vec3]) {
        for (l, o) in out.iter_mut().enumerate() {
            *o = v[l] * self.anchor_n_per_mm[l];
        }
        for s in &self.springs {
            let va = v[s.a as usize];
            let vb = if s.b == NONE {
                Vec3::zeros()
            } else {
                v[s.b as usize]
            };
            let y = sym_block_mul(&s.k, &(va - vb));
            out[s.a as usize] += y;
            if s.b != NONE {
                out[s.b as usize] -= y;
            }
        }
        self.apply_volume(v, out);
    }

    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    pub(super) fn iterate(&mut self) {
        let m = self.nodes.len();
        for dir in 0..3 {
            if self.converged[dir] {
                continue;
            }
            let mut ap = std::mem::take(&mut self.ap[dir]);
            self.apply(&self.p[dir], &mut ap);
            let mut pap = 0.0;
            for l in 0..m {
                if self.role[l] == FREE {
                    pap += self.p[dir][l].dot(&ap[l]);
                }
            }
            if pap.is_nan() || pap <= 1e-20 {
                self.converged[dir] = true;
                self.ap[dir] = ap;
                continue;
            }
            let alpha = self.rz[dir] / pap;
            let mut rz_new = 0.0;
            let mut r_norm2 = 0.0;
            for l in 0..m {
                if self.role[l] != FREE {
                    continue;
                }
                self.u[dir][l] += self.p[dir][l] * alpha;
                self.r[dir][l] -= ap[l] * alpha;
                let z = self.precondition(l, &self.r[dir][l]);
                rz_new += self.r[dir][l].dot(&z);
                r_norm2 += self.r[dir][l].norm_squared();
            }
            let beta = rz_new / self.rz[dir];
            for l in 0..m {
                if self.role[l] == FREE {
                    let z = self.precondition(l, &self.r[dir][l]);
                    self.p[dir][l] = z + self.p[dir][l] * beta;
                }
            }
            self.rz[dir] = rz_new;
            self.ap[dir] = ap;
            if r_norm2.sqrt() <= Self::TOLERANCE * self.b_norm[dir] || !rz_new.is_finite() {
                self.converged[dir] = true;
            }
        }
        self.iterations += 1;
    }

    #[allow(clippy::needless_range_loop)] // several buffers indexed in step
    pub(super) fn finish(&mut self) {
        let m = self.nodes.len();
        // K_ij = u_i . A u_j and D_ij = u_i . C u_j over the solved modes: the normal one for a push
        // (K = k_n n n^T), the three axes for a grasp (the full 3x3 Schur complement).
        let modes = if self.full { 3 } else { 1 };
        for j in 0..modes {
            let mut au = std::mem::take(&mut self.ap[j]);
            self.apply(&self.u[j], &mut au);
            self.ap[j] = au;
        }
        let mut k = Matrix3::zeros();
        let mut d = Matrix3::zeros();
        for i in 0..modes {
            for j in 0..modes {
                let mut k_ij = 0.0;
                let mut d_ij = 0.0;
                for l in 0..m {
                    k_ij += self.u[i][l].dot(&self.ap[j][l]);
                    d_ij += self.drag_n_s_per_mm[l] * self.u[i][l].dot(&self.u[j][l]);
                }
                for s in &self.springs {
                    let along = |u: &[Vec3]| {
                        let ub = if s.b == NONE {
                            Vec3::zeros()
                        } else {
                            u[s.b as usize]
                        };
                        (u[s.a as usize] - ub).dot(&s.dir)
                    };
                    d_ij += s.c * (along(&self.u[i]) * along(&self.u[j]));
                }
                k[(i, j)] = k_ij;
                d[(i, j)] = d_ij;
            }
        }
        let finite = k.iter().chain(d.iter()).all(|v| v.is_finite());
        let (stiffness, damping) = if !finite {
            (Matrix3::zeros(), Matrix3::zeros())
        } else if self.full {
            // The axes are the world's: K is the matrix itself (symmetrised: the solve is inexact).
            (
                psd_part(&((k + k.transpose()) * 0.5)),
                psd_part(&((d + d.transpose()) * 0.5)),
            )
        } else {
            let nn = self.normal * self.normal.transpose();
            (nn * k[(0, 0)].max(0.0), nn * d[(0, 0)].max(0.0))
        };
        self.result = Some(ContactResponse {
            stiffness_n_per_mm: stiffness,
            damping_n_s_per_mm: damping,
            full: self.full,
            iterations: self.iterations,
            nodes: m as u32,
        });
        self.solving = false;
        if self.warm_start {
            self.warm_nodes.clear();
            self.warm_nodes.extend_from_slice(&self.nodes);
            for (warm, u) in self.warm_u.iter_mut().zip(&self.u) {
                warm.clear();
                warm.extend_from_slice(u);
            }
            self.warm_full = self.full;
        }
    }
}

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
        // k_n = u . A u and d_n = u . C u of the normal mode; K = k_n n n^T, D = d_n n n^T.
        let mut au = std::mem::take(&mut self.ap[0]);
        self.apply(&self.u[0], &mut au);
        let mut k_n = 0.0;
        let mut d_n = 0.0;
        for l in 0..m {
            k_n += self.u[0][l].dot(&au[l]);
            d_n += self.drag_n_s_per_mm[l] * self.u[0][l].norm_squared();
        }
        for s in &self.springs {
            let ua = self.u[0][s.a as usize];
            let ub = if s.b == NONE {
                Vec3::zeros()
            } else {
                self.u[0][s.b as usize]
            };
            d_n += s.c * (ua - ub).dot(&s.dir).powi(2);
        }
        self.ap[0] = au;
        let nn = self.normal * self.normal.transpose();
        let finite = k_n.is_finite() && d_n.is_finite();
        self.result = Some(ContactResponse {
            stiffness_n_per_mm: if finite {
                nn * k_n.max(0.0)
            } else {
                Matrix3::zeros()
            },
            damping_n_s_per_mm: if finite {
                nn * d_n.max(0.0)
            } else {
                Matrix3::zeros()
            },
            iterations: self.iterations,
            nodes: m as u32,
        });
        self.solving = false;
    }
}

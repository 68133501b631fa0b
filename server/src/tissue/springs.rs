//! The springs of one object in structure-of-arrays layout, and the force kernel that every integrator calls.
//!
//! Owns: edge endpoints, rest lengths, stiffness and damping, sorted by first endpoint so node accesses stay
//! local. The kernel works in blocks of [`LANES`] springs: gather the endpoint differences into small arrays,
//! do the arithmetic (square root, division, law, damping) lane by lane so the compiler emits packed SIMD, then
//! scatter. Real-time contract of every function here: no allocation, never blocks, never panics on non-finite
//! input (a zero-length edge contributes nothing).

use super::Vec3;
use super::spring_law::SpringLaw;

/// Springs per block of the kernel (two SSE or one AVX register of f32).
pub const LANES: usize = 8;

/// Springs in SoA layout.
#[derive(Debug, Clone, Default)]
pub struct SpringSet {
    /// First endpoint (the sort key).
    pub a: Vec<u32>,
    /// Second endpoint.
    pub b: Vec<u32>,
    /// Rest length, mm.
    pub rest_mm: Vec<f32>,
    /// Small-strain stiffness, N/mm.
    pub stiffness_n_per_mm: Vec<f32>,
    /// Damping along the edge, N s/mm.
    pub damping_n_s_per_mm: Vec<f32>,
}

/// The state of one spring at the current positions, for the implicit integrator's Jacobian.
#[derive(Debug, Clone, Copy, Default)]
pub struct SpringJacobian {
    /// Symmetric 3x3 block `d f_a / d x_b` scaled and combined for the system matrix: xx, yy, zz, xy, xz, yz.
    pub block: [f32; 6],
}

impl SpringSet {
    /// Number of springs.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// No springs.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Append one spring.
    pub fn push(&mut self, a: u32, b: u32, rest_mm: f32, k: f32, c: f32) {
        self.a.push(a);
        self.b.push(b);
        self.rest_mm.push(rest_mm);
        self.stiffness_n_per_mm.push(k);
        self.damping_n_s_per_mm.push(c);
    }

    /// Spring `s` as a tuple (a, b, rest, k, c).
    #[inline(always)]
    pub fn get(&self, s: usize) -> (usize, usize, f32, f32, f32) {
        (
            self.a[s] as usize,
            self.b[s] as usize,
            self.rest_mm[s],
            self.stiffness_n_per_mm[s],
            self.damping_n_s_per_mm[s],
        )
    }

    /// Add every spring's spring-plus-damper force to `forces_n` (end `a` gets `+f`, end `b` gets `-f`).
    pub fn accumulate_forces(
        &self,
        law: SpringLaw,
        positions_mm: &[Vec3],
        velocities_mm_s: &[Vec3],
        forces_n: &mut [Vec3],
    ) {
        // One monomorphised kernel per law: the law's branch leaves the inner loop.
        match law {
            SpringLaw::Linear => {
                self.kernel(|s, _rest, k| k * s, positions_mm, velocities_mm_s, forces_n)
            }
            other => self.kernel(
                |s, rest, k| other.tension_n(s, rest, k),
                positions_mm,
                velocities_mm_s,
                forces_n,
            ),
        }
    }

    #[inline(always)]
    fn kernel(
        &self,
        tension: impl Fn(f32, f32, f32) -> f32,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
    ) {
        let n = self.len();
        let blocks = n / LANES;
        for block in 0..blocks {
            let base = block * LANES;
            let a = &self.a[base..base + LANES];
            let b = &self.b[base..base + LANES];
            let rest = &self.rest_mm[base..base + LANES];
            let k = &self.stiffness_n_per_mm[base..base + LANES];
            let c = &self.damping_n_s_per_mm[base..base + LANES];
            let (mut dx, mut dy, mut dz) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
            let (mut ux, mut uy, mut uz) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
            for j in 0..LANES {
                let (ia, ib) = (a[j] as usize, b[j] as usize);
                let d = x[ib] - x[ia];
                let dv = v[ib] - v[ia];
                dx[j] = d.x;
                dy[j] = d.y;
                dz[j] = d.z;
                ux[j] = dv.x;
                uy[j] = dv.y;
                uz[j] = dv.z;
            }
            let mut scale = [0.0f32; LANES];
            for j in 0..LANES {
                let len2 = dx[j] * dx[j] + dy[j] * dy[j] + dz[j] * dz[j];
                let len = len2.sqrt();
                let inv = if len > 1e-9 { 1.0 / len } else { 0.0 };
                let rate = (ux[j] * dx[j] + uy[j] * dy[j] + uz[j] * dz[j]) * inv;
                scale[j] = (tension(len - rest[j], rest[j], k[j]) + c[j] * rate) * inv;
            }
            for j in 0..LANES {
                let fj = Vec3::new(dx[j], dy[j], dz[j]) * scale[j];
                f[a[j] as usize] += fj;
                f[b[j] as usize] -= fj;
            }
        }
        for s in blocks * LANES..n {
            let (ia, ib, rest, k, c) = self.get(s);
            let fj = one_spring(&tension, x[ib] - x[ia], v[ib] - v[ia], rest, k, c);
            f[ia] += fj;
            f[ib] -= fj;
        }
    }

    /// Force of spring `s` on its end `a`, N.
    #[inline(always)]
    pub fn force_on_a(&self, law: SpringLaw, s: usize, x: &[Vec3], v: &[Vec3]) -> Vec3 {
        let (ia, ib, rest, k, c) = self.get(s);
        one_spring(
            &|s, rest, k| law.tension_n(s, rest, k),
            x[ib] - x[ia],
            v[ib] - v[ia],
            rest,
            k,
            c,
        )
    }

    /// For the implicit integrator: per spring, the 3x3 block `h c u u^T + h^2 J` where `J = d f_a / d x_b` with
    /// the geometric term clamped to tension (a compressed spring's negative term would make the system
    /// indefinite). Also returns nothing else; the caller multiplies with [`Self::add_block_products`].
    pub fn implicit_blocks(&self, law: SpringLaw, x: &[Vec3], h: f32, out: &mut [SpringJacobian]) {
        for (s, out) in out.iter_mut().enumerate().take(self.len()) {
            let (ia, ib, rest, k, c) = self.get(s);
            let d = x[ib] - x[ia];
            let len = d.norm();
            if len <= 1e-9 {
                *out = SpringJacobian::default();
                continue;
            }
            let u = d / len;
            let stretch = len - rest;
            let kt = law.tangent_n_per_mm(stretch, rest, k);
            let geometric = (law.tension_n(stretch, rest, k) / len).max(0.0);
            // J = kt uu^T + geometric (I - uu^T); block = h c uu^T + h^2 J.
            let along = h * c + h * h * (kt - geometric);
            let iso = h * h * geometric;
            out.block = [
                along * u.x * u.x + iso,
                along * u.y * u.y + iso,
                along * u.z * u.z + iso,
                along * u.x * u.y,
                along * u.x * u.z,
                along * u.y * u.z,
            ];
        }
    }

    /// `out_a -= B (p_b - p_a)`, `out_b += B (p_b - p_a)` for every spring block `B`: the spring part of
    /// `(-h C - h^2 K) p`, added to `out`.
    pub fn add_block_products(&self, blocks: &[SpringJacobian], p: &[Vec3], out: &mut [Vec3]) {
        for (s, jac) in blocks.iter().enumerate().take(self.len()) {
            let (ia, ib) = (self.a[s] as usize, self.b[s] as usize);
            let r = p[ib] - p[ia];
            let m = &jac.block;
            let y = Vec3::new(
                m[0] * r.x + m[3] * r.y + m[4] * r.z,
                m[3] * r.x + m[1] * r.y + m[5] * r.z,
                m[4] * r.x + m[5] * r.y + m[2] * r.z,
            );
            out[ia] -= y;
            out[ib] += y;
        }
    }

    /// Add each block's diagonal to both endpoints' entries of `diag` (Jacobi preconditioner).
    pub fn add_block_diagonals(&self, blocks: &[SpringJacobian], diag: &mut [Vec3]) {
        for (s, jac) in blocks.iter().enumerate().take(self.len()) {
            let d = Vec3::new(jac.block[0], jac.block[1], jac.block[2]);
            diag[self.a[s] as usize] += d;
            diag[self.b[s] as usize] += d;
        }
    }
}

#[inline(always)]
fn one_spring(
    tension: &impl Fn(f32, f32, f32) -> f32,
    d: Vec3,
    dv: Vec3,
    rest: f32,
    k: f32,
    c: f32,
) -> Vec3 {
    let len = d.norm();
    if len <= 1e-9 {
        return Vec3::zeros();
    }
    let inv = 1.0 / len;
    let rate = dv.dot(&d) * inv;
    d * ((tension(len - rest, rest, k) + c * rate) * inv)
}

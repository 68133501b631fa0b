//! The springs of one object in structure-of-arrays layout, and the force kernel that every integrator calls.
//!
//! Owns: edge endpoints, rest lengths, stiffness and damping, sorted by first endpoint so node accesses stay
//! local, and the kernel's padded scratch. The kernel copies positions and velocities into 16-byte-aligned
//! four-float slots ([`Padded`]), so each endpoint difference is one packed subtraction and each force
//! scatter one aligned packed read-modify-write; then it adds the padded forces back. Measured on the pad
//! (14,540 springs, one core): 83 us with three-float scalar gathers and scatters (also with an 8-lane
//! structure-of-arrays block variant, and with unaligned 16-byte loads, whose overlapping read-modify-writes
//! defeat store forwarding), 55 us for this kernel plus about 9 us of copies. Real-time contract of every
//! function here: no allocation once the scratch is sized, never blocks, never panics on non-finite input (a
//! zero-length edge contributes nothing).
//!
//! With more than one thread ([`sinew_parallel::ChunkRunner`]) the same forces come from three passes over
//! fixed chunks: the padded copies by node chunk, each spring's force into its own slot by spring chunk, then
//! each node gathers its springs' slots in spring order by node chunk. Each node adds the very same products
//! in the very same order as the one-thread scatter, so every thread count, one included, gives the same
//! bits. The elastic energy sums fixed chunks of [`SPRING_CHUNK`] springs, then the chunks in order, on any
//! thread count.

use super::Vec3;
use super::spring_law::SpringLaw;
use sinew_parallel::{ChunkRunner, chunk_count, chunk_range, for_chunks_mut, for_chunks_mut2};

/// Springs per chunk of the parallel passes (a multiple of the energy kernel's block of 8). Fixed: the energy's
/// partial sums, and so its bits, depend on it, never on the thread count.
pub const SPRING_CHUNK: usize = 1024;
/// Nodes per chunk of the parallel passes.
pub const NODE_CHUNK: usize = 512;

/// A 3-vector in a 16-byte-aligned four-float slot (the fourth lane stays zero).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(16))]
pub struct Padded(pub [f32; 4]);

impl Padded {
    #[inline(always)]
    fn from_vec3(v: &Vec3) -> Self {
        Padded([v.x, v.y, v.z, 0.0])
    }

    #[inline(always)]
    fn minus(&self, other: &Padded) -> [f32; 4] {
        let (a, b) = (&self.0, &other.0);
        [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
    }
}

/// The kernel's padded copies of positions, velocities and forces (sized to the node count on first use),
/// each spring's force for the parallel gather, and the energy's per-chunk partial sums.
#[derive(Debug, Clone, Default)]
pub struct KernelScratch {
    x: Vec<Padded>,
    v: Vec<Padded>,
    f: Vec<Padded>,
    per_spring: Vec<Padded>,
    energy_partials: Vec<f64>,
}

impl KernelScratch {
    /// Size the per-node buffers for `n` nodes (allocates only when they grow past their capacity).
    fn fit_nodes(&mut self, n: usize) {
        for buffer in [&mut self.x, &mut self.v, &mut self.f] {
            if buffer.len() != n {
                buffer.resize(n, Padded::default());
            }
        }
    }
}

/// What a force pass reads: the law, the positions, the velocities (none: springs only, a static solve), and
/// each node's own force before the springs (`base_n(i)`: anchor, gravity, external), N.
#[derive(Debug, Clone, Copy)]
pub struct ForcePass<'a, B> {
    /// The spring law.
    pub law: SpringLaw,
    /// Node positions, mm.
    pub positions_mm: &'a [Vec3],
    /// Node velocities, mm/s (`None`: no dampers).
    pub velocities_mm_s: Option<&'a [Vec3]>,
    /// Each node's own force, N.
    pub base_n: B,
}

/// Node -> incident springs in spring order (compressed rows): the springs touching node `i` are
/// `list[start[i]..start[i + 1]]`. The parallel gather reads it.
#[derive(Debug, Clone, Copy)]
pub struct NodeSprings<'a> {
    /// Row starts, one per node plus one.
    pub start: &'a [u32],
    /// Spring indices, ascending within each row.
    pub list: &'a [u32],
}

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

/// The tangent stiffness of one spring, `J = kt uu^T + g (I - uu^T)` (N/mm), split into its parts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringTangent {
    /// Unit direction from end a to end b.
    pub dir: Vec3,
    /// `kt - g`: the stiffness along `dir` beyond the isotropic part, N/mm.
    pub along_n_per_mm: f32,
    /// `g = max(T, 0) / len`: the geometric (tension) stiffness, the same in every direction, N/mm.
    pub iso_n_per_mm: f32,
}

/// The tangent of the spring from `xa` to `xb` with rest length `rest` and stiffness `k` under `law`; `None`
/// for a degenerate (zero or non-finite length) spring. The geometric term is clamped at zero in compression,
/// so the block stays positive semi-definite. Shared by the implicit integrators and the contact solve.
pub fn spring_tangent(
    law: SpringLaw,
    xa: Vec3,
    xb: Vec3,
    rest: f32,
    k: f32,
) -> Option<SpringTangent> {
    let d = xb - xa;
    let len = d.norm();
    if !len.is_finite() || len <= 1e-9 {
        return None;
    }
    let stretch = len - rest;
    let kt = law.tangent_n_per_mm(stretch, rest, k);
    let geometric = (law.tension_n(stretch, rest, k) / len).max(0.0);
    Some(SpringTangent {
        dir: d / len,
        along_n_per_mm: kt - geometric,
        iso_n_per_mm: geometric,
    })
}

/// The symmetric block `along uu^T + iso I`, stored xx, yy, zz, xy, xz, yz.
pub fn sym_block(along: f32, iso: f32, u: &Vec3) -> [f32; 6] {
    [
        along * u.x * u.x + iso,
        along * u.y * u.y + iso,
        along * u.z * u.z + iso,
        along * u.x * u.y,
        along * u.x * u.z,
        along * u.y * u.z,
    ]
}

/// `m r` for a symmetric block stored xx, yy, zz, xy, xz, yz.
pub fn sym_block_mul(m: &[f32; 6], r: &Vec3) -> Vec3 {
    Vec3::new(
        m[0] * r.x + m[3] * r.y + m[4] * r.z,
        m[3] * r.x + m[1] * r.y + m[5] * r.z,
        m[4] * r.x + m[5] * r.y + m[2] * r.z,
    )
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

    /// Remove every spring (keeps the buffers).
    pub fn clear(&mut self) {
        self.a.clear();
        self.b.clear();
        self.rest_mm.clear();
        self.stiffness_n_per_mm.clear();
        self.damping_n_s_per_mm.clear();
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

    /// Write into `forces_n` each node's `base_n(i)` plus every spring's force (end `a` gets `+f`, end `b`
    /// gets `-f`); with `velocities_mm_s` the dampers too, without them springs only (a static solve). On a
    /// runner with more than one thread the passes are spread over it through `incidence` (the same bits).
    pub fn forces_into<B: Fn(usize) -> Vec3 + Sync>(
        &self,
        pass: ForcePass<'_, B>,
        forces_n: &mut [Vec3],
        scratch: &mut KernelScratch,
        runner: &dyn ChunkRunner,
        incidence: NodeSprings<'_>,
    ) {
        let n = pass.positions_mm.len().min(forces_n.len());
        if runner.threads() > 1 && incidence.start.len() > n {
            self.gather_forces(pass, forces_n, scratch, runner, incidence);
        } else {
            self.scatter_forces(pass, forces_n, scratch);
        }
    }

    /// The one-thread kernel: each spring scatters its force into both ends.
    fn scatter_forces<B: Fn(usize) -> Vec3>(
        &self,
        pass: ForcePass<'_, B>,
        forces_n: &mut [Vec3],
        scratch: &mut KernelScratch,
    ) {
        scratch.fit_nodes(pass.positions_mm.len().min(forces_n.len()));
        for (i, (px, pf)) in scratch.x.iter_mut().zip(scratch.f.iter_mut()).enumerate() {
            *px = Padded::from_vec3(&pass.positions_mm[i]);
            *pf = Padded::from_vec3(&(pass.base_n)(i));
        }
        // One monomorphised kernel per law and per damping: the branches leave the inner loop.
        match (pass.law, pass.velocities_mm_s) {
            (SpringLaw::Linear, None) => self.kernel::<false>(|s, _rest, k| k * s, scratch),
            (other, None) => {
                self.kernel::<false>(|s, rest, k| other.tension_n(s, rest, k), scratch)
            }
            (law, Some(v)) => {
                for (pv, v) in scratch.v.iter_mut().zip(v) {
                    *pv = Padded::from_vec3(v);
                }
                match law {
                    SpringLaw::Linear => self.kernel::<true>(|s, _rest, k| k * s, scratch),
                    other => self.kernel::<true>(|s, rest, k| other.tension_n(s, rest, k), scratch),
                }
            }
        }
        for (f, p) in forces_n.iter_mut().zip(&scratch.f) {
            *f = Vec3::new(p.0[0], p.0[1], p.0[2]);
        }
    }

    /// The passes over `runner`: padded copies by node, each spring's force into its slot, each node's gather.
    fn gather_forces<B: Fn(usize) -> Vec3 + Sync>(
        &self,
        pass: ForcePass<'_, B>,
        forces_n: &mut [Vec3],
        scratch: &mut KernelScratch,
        runner: &dyn ChunkRunner,
        incidence: NodeSprings<'_>,
    ) {
        let ForcePass {
            law,
            positions_mm,
            velocities_mm_s,
            base_n,
        } = pass;
        let n = positions_mm.len().min(forces_n.len());
        let m = self.len();
        scratch.fit_nodes(n);
        let KernelScratch {
            x,
            v,
            f,
            per_spring,
            ..
        } = scratch;
        if per_spring.len() != m {
            per_spring.resize(m, Padded::default());
        }
        // Pass 1, by node: the padded copies, and each node's own force.
        for_chunks_mut2(runner, x, f, NODE_CHUNK, |c, xs, fs| {
            for ((px, pf), i) in xs.iter_mut().zip(fs).zip(chunk_range(c, n, NODE_CHUNK)) {
                *px = Padded::from_vec3(&positions_mm[i]);
                *pf = Padded::from_vec3(&base_n(i));
            }
        });
        if let Some(velocities) = velocities_mm_s {
            for_chunks_mut(runner, v, NODE_CHUNK, |c, vs| {
                for (pv, i) in vs.iter_mut().zip(chunk_range(c, n, NODE_CHUNK)) {
                    *pv = Padded::from_vec3(&velocities[i]);
                }
            });
        }
        // Pass 2, by spring: each spring's force on its end a, into its own slot.
        let (x, v) = (&*x, &*v);
        for_chunks_mut(runner, per_spring, SPRING_CHUNK, |c, out| {
            let (springs, damped) = (chunk_range(c, m, SPRING_CHUNK), velocities_mm_s.is_some());
            match law {
                SpringLaw::Linear => {
                    self.spring_slots(damped, |s, _rest, k| k * s, x, v, springs, out)
                }
                other => self.spring_slots(
                    damped,
                    |s, rest, k| other.tension_n(s, rest, k),
                    x,
                    v,
                    springs,
                    out,
                ),
            }
        });
        // Pass 3, by node: the node's own force plus its springs' slots, in spring order (the scatter's order).
        let (f, per_spring) = (&*f, &*per_spring);
        for_chunks_mut(runner, &mut forces_n[..n], NODE_CHUNK, |c, out| {
            for (force, i) in out.iter_mut().zip(chunk_range(c, n, NODE_CHUNK)) {
                let mut sum = f[i].0;
                let row = incidence.start[i] as usize..incidence.start[i + 1] as usize;
                for &s in incidence.list.get(row).unwrap_or(&[]) {
                    let Some(spring) = per_spring.get(s as usize) else {
                        continue;
                    };
                    if self.a[s as usize] as usize == i {
                        for (acc, q) in sum.iter_mut().zip(spring.0) {
                            *acc += q;
                        }
                    } else {
                        for (acc, q) in sum.iter_mut().zip(spring.0) {
                            *acc -= q;
                        }
                    }
                }
                *force = Vec3::new(sum[0], sum[1], sum[2]);
            }
        });
    }

    /// [`Self::spring_forces`], monomorphised with and without dampers (the branch leaves the inner loop).
    #[inline(always)]
    fn spring_slots(
        &self,
        damped: bool,
        tension: impl Fn(f32, f32, f32) -> f32,
        x: &[Padded],
        v: &[Padded],
        springs: std::ops::Range<usize>,
        out: &mut [Padded],
    ) {
        if damped {
            self.spring_forces::<true>(tension, x, v, springs, out);
        } else {
            self.spring_forces::<false>(tension, x, v, springs, out);
        }
    }

    /// Each spring of `springs`' force on its end a (the scatter kernel's `d * scale`, to the bit) into `out`.
    #[inline(always)]
    fn spring_forces<const DAMPED: bool>(
        &self,
        tension: impl Fn(f32, f32, f32) -> f32,
        x: &[Padded],
        v: &[Padded],
        springs: std::ops::Range<usize>,
        out: &mut [Padded],
    ) {
        for (slot, s) in out.iter_mut().zip(springs) {
            *slot = match self.spring_along::<DAMPED>(&tension, x, v, s) {
                Some((_, _, d, scale)) => {
                    Padded([d[0] * scale, d[1] * scale, d[2] * scale, d[3] * scale])
                }
                None => Padded::default(),
            };
        }
    }

    /// Spring `s`'s endpoints, its end-to-end difference `d` (padded) and the factor `scale` that makes
    /// `d * scale` its force on end a: the one computation both kernels share, so they agree to the bit.
    /// `None` when an endpoint is out of range.
    #[inline(always)]
    fn spring_along<const DAMPED: bool>(
        &self,
        tension: &impl Fn(f32, f32, f32) -> f32,
        x: &[Padded],
        v: &[Padded],
        s: usize,
    ) -> Option<(usize, usize, [f32; 4], f32)> {
        let (a, b) = (self.a[s] as usize, self.b[s] as usize);
        let (xa, xb) = (x.get(a)?, x.get(b)?);
        let d = xb.minus(xa);
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let inv = if len > 1e-9 { 1.0 / len } else { 0.0 };
        let rest = self.rest_mm[s];
        let mut magnitude = tension(len - rest, rest, self.stiffness_n_per_mm[s]);
        if DAMPED && let (Some(va), Some(vb)) = (v.get(a), v.get(b)) {
            let dv = vb.minus(va);
            let rate = (dv[0] * d[0] + dv[1] * d[1] + dv[2] * d[2]) * inv;
            magnitude += self.damping_n_s_per_mm[s] * rate;
        }
        Some((a, b, d, magnitude * inv))
    }

    #[inline(always)]
    fn kernel<const DAMPED: bool>(
        &self,
        tension: impl Fn(f32, f32, f32) -> f32,
        scratch: &mut KernelScratch,
    ) {
        let (x, v, f) = (&scratch.x, &scratch.v, &mut scratch.f);
        for s in 0..self.len() {
            let Some((a, b, d, scale)) = self.spring_along::<DAMPED>(&tension, x, v, s) else {
                continue;
            };
            if let Some(fa) = f.get_mut(a) {
                for (out, dq) in fa.0.iter_mut().zip(d) {
                    *out += dq * scale;
                }
            }
            if let Some(fb) = f.get_mut(b) {
                for (out, dq) in fb.0.iter_mut().zip(d) {
                    *out -= dq * scale;
                }
            }
        }
    }

    /// Add each spring's tangent stiffness at these positions to both endpoints' entries of `diagonal`, N/mm
    /// (quasi-static relaxation with a stiffening law).
    pub fn accumulate_tangent_diagonal(&self, law: SpringLaw, x: &[Vec3], diagonal: &mut [f32]) {
        for s in 0..self.len() {
            let (ia, ib, rest, k, _) = self.get(s);
            let kt = law.tangent_n_per_mm((x[ib] - x[ia]).norm() - rest, rest, k);
            diagonal[ia] += kt;
            diagonal[ib] += kt;
        }
    }

    /// Elastic energy stored in every spring at these positions, N mm (= mJ). A pure reduction: each chunk of
    /// [`SPRING_CHUNK`] springs sums into its own partial (blocks of eight springs gather their endpoint
    /// differences, then take eight square roots at once), then the partials add up in chunk order.
    pub fn energy_n_mm(
        &self,
        law: SpringLaw,
        x: &[Vec3],
        runner: &dyn ChunkRunner,
        scratch: &mut KernelScratch,
    ) -> f64 {
        let m = self.len();
        let partials = &mut scratch.energy_partials;
        partials.clear();
        partials.resize(chunk_count(m, SPRING_CHUNK), 0.0);
        for_chunks_mut(runner, partials, 1, |c, partial| {
            let springs = chunk_range(c, m, SPRING_CHUNK);
            partial[0] = match law {
                SpringLaw::Linear => self.energy_kernel(|s, _rest, k| 0.5 * k * s * s, x, springs),
                other => self.energy_kernel(|s, rest, k| other.energy_n_mm(s, rest, k), x, springs),
            };
        });
        partials.iter().fold(0.0, |total, p| total + p)
    }

    #[inline(always)]
    fn energy_kernel(
        &self,
        energy: impl Fn(f32, f32, f32) -> f32,
        x: &[Vec3],
        springs: std::ops::Range<usize>,
    ) -> f64 {
        const BLOCK: usize = 8;
        let mut total = 0.0f64;
        let blocks = springs.len() / BLOCK;
        for block in 0..blocks {
            let base = springs.start + block * BLOCK;
            let mut len2 = [0.0f32; BLOCK];
            for (j, l) in len2.iter_mut().enumerate() {
                let (a, b) = (self.a[base + j] as usize, self.b[base + j] as usize);
                if let (Some(xa), Some(xb)) = (x.get(a), x.get(b)) {
                    *l = (xb - xa).norm_squared();
                }
            }
            let mut sum = 0.0f32;
            for (j, l) in len2.iter().enumerate() {
                let rest = self.rest_mm[base + j];
                sum += energy(l.sqrt() - rest, rest, self.stiffness_n_per_mm[base + j]);
            }
            total += f64::from(sum);
        }
        for s in springs.start + blocks * BLOCK..springs.end {
            let (ia, ib, rest, k, _) = self.get(s);
            if let (Some(xa), Some(xb)) = (x.get(ia), x.get(ib)) {
                total += f64::from(energy((xb - xa).norm() - rest, rest, k));
            }
        }
        total
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
    /// indefinite), written into `out`; [`Self::add_block_products`] multiplies with them.
    pub fn implicit_blocks(&self, law: SpringLaw, x: &[Vec3], h: f32, out: &mut [SpringJacobian]) {
        for (s, out) in out.iter_mut().enumerate().take(self.len()) {
            let (ia, ib, rest, k, c) = self.get(s);
            // block = h c uu^T + h^2 J.
            out.block = match spring_tangent(law, x[ia], x[ib], rest, k) {
                Some(t) => sym_block(
                    h * c + h * h * t.along_n_per_mm,
                    h * h * t.iso_n_per_mm,
                    &t.dir,
                ),
                None => SpringJacobian::default().block,
            };
        }
    }

    /// `out_a -= B (p_b - p_a)`, `out_b += B (p_b - p_a)` for every spring block `B`: the spring part of
    /// `(-h C - h^2 K) p`, added to `out`.
    pub fn add_block_products(&self, blocks: &[SpringJacobian], p: &[Vec3], out: &mut [Vec3]) {
        for (s, jac) in blocks.iter().enumerate().take(self.len()) {
            let (ia, ib) = (self.a[s] as usize, self.b[s] as usize);
            let y = sym_block_mul(&jac.block, &(p[ib] - p[ia]));
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

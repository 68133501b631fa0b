//! The thread chain's implicit step, solved by Newton's method in the nodes' positions, in f64.
//!
//! Owns: [`PositionSolve`] (its scratch), [`ChainTerms`] (what the step's energy is made of) and [`NodeSlide`]
//! (a node the material slides through). Each substep minimises `sum m_i |x_i - p_i|^2 / (2 h^2)` (inertia
//! about the prediction `p`) plus each segment's spring `k (|d| - l)^2 / 2` (`k = EA / l`), the holds' springs
//! (`NodeHold`) and the hinges' bending `k_b |c|^2 / 2` (`c` a node's offset from its neighbours' midpoint across
//! their chord).
//! - **Sliding nodes.** A segment's rest length is the difference of its nodes' material coordinates,
//!   `l = u_b - u_a`. At a node a hole holds while the thread slides through it, `u` is a variable of the
//!   solve too (Sueda et al. 2011), with the node's mass as its inertia about `u + u' h` and the friction as a
//!   constant force against the way it slides (Coulomb's kinetic law; the step may not turn it back, nor
//!   bring a neighbour nearer than a bound): the whole thread then runs through the hole in one implicit step,
//!   with its inertia either side. A node's unknowns are its position and `u`, so the blocks are 4x4 (`u`
//!   pinned where it does not slide); `k` is frozen over the step.
//! - **Direct.** A segment couples two nodes and a hinge three, so the system is block tridiagonal in 3x3
//!   blocks once the hinge's coupling between its two neighbours is moved onto their diagonal (an upper bound
//!   of the Hessian: positive definite; dropped, the matrix went indefinite and the step uphill). Block
//!   elimination solves it exactly in O(n).
//! - **The geometric stiffness.** A segment's Hessian block is `k (n n^T + max(0, 1 - l / |d|) (I - n n^T))`.
//!   The second term, `T / |d|` across a stretched segment, holds a thread pulled taut between two held nodes
//!   straight: the earlier solve in the constraints' multipliers dropped it, and a nearly straight taut chain
//!   bent by `theta` threw a 0.2 mg node sideways by about `T theta h^2 / m` (millimetres), a zigzag that never
//!   converged. It is left out for a slack segment (it would make the step indefinite).
//! - **Downhill.** A step that would not lower the energy is halved (backtracking), and the hinges' chords are
//!   frozen for a step so the energy and its gradient agree.
//! - **f64.** The tension is read from the stretch (`k (|d| - l)`); at `k` = 427 N/mm a micrometre is 0.43 N,
//!   and f32 positions 10-100 mm from the origin resolve 1-8 micrometres (a loose thread read 0.1-1.4 N in f32).
//!   Newton steps run until the largest move is under [`CONVERGED_MM`].
//!
//! Must not: allocate once built, or panic on any input (a singular or non-finite step moves nothing).

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3, Vector4};

use super::NodeHold;
use crate::tissue::MM_PER_M;

/// A position in f64, mm.
pub type V64 = Vector3<f64>;
type M64 = Matrix3<f64>;
type M4 = Matrix4<f64>;
type V4 = Vector4<f64>;

/// A Newton step moving no node further than this has converged, mm.
pub const CONVERGED_MM: f64 = 1e-7;
/// Times a Newton step is halved when it would not lower the energy.
const LINE_SEARCH_HALVINGS: usize = 8;

/// The material sliding through a node for one step (a hole the thread runs through, `thread_hole.rs`): its
/// material coordinate `u` is a variable, predicted at `predicted_u_mm`, pushed by `friction_n` (N, toward
/// falling `u` when positive: against the way it slides) and kept within `lo_mm..=hi_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeSlide {
    /// Where inertia alone takes `u`, mm.
    pub predicted_u_mm: f64,
    /// The friction's force on `u`, N (positive: toward falling `u`).
    pub friction_n: f64,
    /// The least and most `u` the step may reach, mm.
    pub lo_mm: f64,
    /// See `lo_mm`.
    pub hi_mm: f64,
    /// The thread's direction at the node, toward rising `u` (unit): the material there moves at
    /// `x' - tangent u'` (the node moving along with the material is no motion of it).
    pub tangent: V64,
}

/// What the step's energy is made of: per node the inverse mass (1/kg; 0: held, it does not move), the hold and
/// the slide (if any), per segment the spring (N/mm), and the hinges' bending stiffness (N/mm). The rest
/// lengths are the differences of the nodes' material coordinates.
#[derive(Debug, Clone, Copy)]
pub struct ChainTerms<'a> {
    /// Per node, 1/kg.
    pub inverse_mass_per_kg: &'a [f32],
    /// Per node.
    pub holds: &'a [Option<NodeHold>],
    /// Per node.
    pub slides: &'a [Option<NodeSlide>],
    /// Per segment, N/mm.
    pub stiffness_n_per_mm: &'a [f32],
    /// Every hinge's, N/mm (0: none).
    pub bend_n_per_mm: f32,
}

impl ChainTerms<'_> {
    fn free(&self, i: usize) -> bool {
        self.inverse_mass_per_kg[i] != 0.0
    }
}

/// The solver's scratch for a chain of `n` nodes.
#[derive(Debug, Clone)]
pub struct PositionSolve {
    before: Vec<V64>,
    u_before: Vec<f64>,
    /// Per node, its slide reached a bound in this step and is held there (an active set).
    pinned: Vec<bool>,
    block_inv: Vec<M4>,
    block_off: Vec<M4>,
    rhs: Vec<V4>,
    chord: Vec<V64>,
    /// The 3x3 system when nothing slides.
    block3: Vec<M64>,
    off3: Vec<M64>,
    rhs3: Vec<V64>,
}

fn widen_v(v: &V64, u: f64) -> V4 {
    V4::new(v.x, v.y, v.z, u)
}

impl PositionSolve {
    /// Scratch for `n` nodes (allocates).
    pub fn new(n: usize) -> Self {
        Self {
            before: vec![V64::zeros(); n],
            u_before: vec![0.0; n],
            pinned: vec![false; n],
            block_inv: vec![M4::zeros(); n],
            block_off: vec![M4::zeros(); n.saturating_sub(1)],
            rhs: vec![V4::zeros(); n],
            chord: vec![V64::zeros(); n],
            block3: vec![M64::zeros(); n],
            off3: vec![M64::zeros(); n.saturating_sub(1)],
            rhs3: vec![V64::zeros(); n],
        }
    }

    /// Solve the step of `h_s` from the prediction `predicted` (also the start: `x` is set to it first) and the
    /// material coordinates `u` (the sliding nodes' start from their prediction, within their bounds), at most
    /// `max_newton` Newton steps. Returns the steps taken. No allocation.
    pub fn solve(
        &mut self,
        x: &mut [V64],
        u: &mut [f64],
        predicted: &[V64],
        terms: &ChainTerms,
        h_s: f64,
        max_newton: usize,
    ) -> usize {
        x.copy_from_slice(predicted);
        self.pinned.fill(false);
        for (i, u) in u.iter_mut().enumerate() {
            if let Some(slide) = terms.slides[i].filter(|_| terms.free(i)) {
                *u = slide.predicted_u_mm.clamp(slide.lo_mm, slide.hi_mm);
            }
        }
        for k in 0..max_newton {
            match self.newton_step(x, u, predicted, terms, h_s) {
                Some(moved) if moved > CONVERGED_MM => {}
                _ => return k + 1,
            }
        }
        max_newton
    }

    /// Whether node `i`'s material coordinate is a variable of this Newton step.
    fn sliding(&self, terms: &ChainTerms, i: usize) -> bool {
        terms.free(i) && terms.slides[i].is_some() && !self.pinned[i]
    }

    /// One Newton step with its line search. The largest move of a node (None: nothing moved). A slide the
    /// step would carry past its bound is held at the bound and the step solved again without it (the bounds
    /// are an active set: clamping the step instead left it inconsistent, the line search failed, and the
    /// chain was left unsolved with tens of newtons in it).
    fn newton_step(
        &mut self,
        x: &mut [V64],
        u: &mut [f64],
        predicted: &[V64],
        terms: &ChainTerms,
        h_s: f64,
    ) -> Option<f64> {
        let n = x.len();
        for _ in 0..=n {
            self.linear_solve(x, u, predicted, terms, h_s)?;
            let mut newly = false;
            for (i, u) in u.iter_mut().enumerate() {
                let Some(slide) = terms.slides[i].filter(|_| self.sliding(terms, i)) else {
                    continue;
                };
                let to = *u + self.rhs[i][3];
                if to < slide.lo_mm || to > slide.hi_mm {
                    *u = to.clamp(slide.lo_mm, slide.hi_mm);
                    self.pinned[i] = true;
                    newly = true;
                }
            }
            if !newly {
                break;
            }
        }
        let largest = self.rhs.iter().map(|d| d.norm()).fold(0.0, f64::max);
        let energy_before = self.energy(x, u, predicted, terms, h_s);
        self.before.copy_from_slice(x);
        self.u_before.copy_from_slice(u);
        let mut scale = 1.0;
        for _ in 0..=LINE_SEARCH_HALVINGS {
            for i in (0..n).filter(|&i| terms.free(i)) {
                let step = self.rhs[i] * scale;
                x[i] = self.before[i] + step.xyz();
                if let Some(slide) = terms.slides[i].filter(|_| self.sliding(terms, i)) {
                    u[i] = (self.u_before[i] + step[3]).clamp(slide.lo_mm, slide.hi_mm);
                }
            }
            if self.energy(x, u, predicted, terms, h_s) <= energy_before {
                return Some(largest * scale);
            }
            scale *= 0.5;
        }
        x.copy_from_slice(&self.before);
        u.copy_from_slice(&self.u_before);
        None
    }

    /// Assemble the Newton system at `x`, `u` and solve it: the step, per node, into `rhs`. None when it is
    /// singular or not finite. With nothing sliding, every `u` is pinned and the system is solved in 3x3 blocks
    /// (the 4x4 blocks cost the thread 1.5-1.8x its solve in the suture bench).
    fn linear_solve(
        &mut self,
        x: &[V64],
        u: &[f64],
        predicted: &[V64],
        terms: &ChainTerms,
        h_s: f64,
    ) -> Option<()> {
        let n = x.len();
        let system = System {
            x,
            u,
            predicted,
            terms,
            h_s,
            pinned: &self.pinned,
        };
        if (0..n).any(|i| self.sliding(terms, i)) {
            system.assemble(
                &mut self.chord,
                &mut self.block_inv,
                &mut self.block_off,
                &mut self.rhs,
            );
            eliminate(&mut self.block_inv, &self.block_off, &mut self.rhs)?;
        } else {
            system.assemble(
                &mut self.chord,
                &mut self.block3,
                &mut self.off3,
                &mut self.rhs3,
            );
            eliminate(&mut self.block3, &self.off3, &mut self.rhs3)?;
            for (r, r3) in self.rhs.iter_mut().zip(&self.rhs3) {
                *r = widen_v(r3, 0.0);
            }
        }
        self.rhs
            .iter()
            .all(|d| d.iter().all(|c| c.is_finite()))
            .then_some(())
    }

    /// The step's energy at `x`, `u` (the hinges' chords as frozen for this Newton step), N mm.
    fn energy(&self, x: &[V64], u: &[f64], predicted: &[V64], terms: &ChainTerms, h_s: f64) -> f64 {
        let h2 = h_s * h_s;
        let mut e = 0.0;
        for i in 0..x.len() {
            let w = f64::from(terms.inverse_mass_per_kg[i]);
            if w == 0.0 {
                continue;
            }
            let inertia = 1.0 / (w * MM_PER_M as f64 * h2);
            e += match terms.slides[i] {
                Some(slide) => {
                    0.5 * inertia
                        * material_offset(&x[i], u[i], &predicted[i], &slide).norm_squared()
                        + slide.friction_n * u[i]
                }
                None => 0.5 * inertia * (x[i] - predicted[i]).norm_squared(),
            };
            if let Some(hold) = terms.holds[i] {
                let off = x[i] - hold.place_mm.cast::<f64>();
                e += 0.5 * off.dot(&(hold_matrix(&hold) * off));
            }
        }
        for s in 0..x.len() - 1 {
            let stretch = (x[s + 1] - x[s]).norm() - (u[s + 1] - u[s]);
            e += 0.5 * f64::from(terms.stiffness_n_per_mm[s]) * stretch * stretch;
        }
        let kb = f64::from(terms.bend_n_per_mm);
        if kb > 0.0 {
            for i in 1..x.len() - 1 {
                let chord = self.chord[i];
                let offset = x[i] - (x[i - 1] + x[i + 1]) * 0.5;
                let c = offset - chord * chord.dot(&offset);
                e += 0.5 * kb * c.norm_squared();
            }
        }
        e
    }
}

/// The Newton system's inputs at one iterate.
struct System<'a> {
    x: &'a [V64],
    u: &'a [f64],
    predicted: &'a [V64],
    terms: &'a ChainTerms<'a>,
    h_s: f64,
    pinned: &'a [bool],
}

impl System<'_> {
    /// Whether node `i`'s `u` is an unknown (only in 4x4 blocks).
    fn sliding<const D: usize>(&self, i: usize) -> bool {
        D == 4 && self.terms.free(i) && self.terms.slides[i].is_some() && !self.pinned[i]
    }

    /// The system's blocks (`D` 3: positions only; 4: and `u`): the diagonal into `diag`, `A_{i,i+1}` into `off`,
    /// the negative gradient into `rhs`, and the hinges' frozen chords into `chord`.
    fn assemble<const D: usize>(
        &self,
        chord: &mut [V64],
        diag: &mut [SMatrix<f64, D, D>],
        off: &mut [SMatrix<f64, D, D>],
        rhs: &mut [SVector<f64, D>],
    ) {
        let (x, u, terms) = (self.x, self.u, self.terms);
        let n = x.len();
        let h2 = self.h_s * self.h_s;
        let wide = |m: &M64| {
            let mut w = SMatrix::<f64, D, D>::zeros();
            w.fixed_view_mut::<3, 3>(0, 0).copy_from(m);
            w
        };
        let wide_v = |v: &V64, last: f64| {
            let mut w = SVector::<f64, D>::zeros();
            w.fixed_rows_mut::<3>(0).copy_from(v);
            if D == 4 {
                w[3] = last;
            }
            w
        };
        for i in 0..n {
            // A pinned unknown's row is the identity with nothing to move.
            diag[i] = SMatrix::<f64, D, D>::identity();
            rhs[i] = SVector::<f64, D>::zeros();
            if !terms.free(i) {
                continue;
            }
            // m / h^2 in N/mm (kg/s^2 is N/m).
            let inertia = 1.0 / (f64::from(terms.inverse_mass_per_kg[i]) * MM_PER_M as f64 * h2);
            let mut block = M64::identity() * inertia;
            // A sliding node's inertia is its material's, m |e|^2 / (2 h^2) with e = (x - p) - t (u - u_p) (held
            // at a bound: about where it is held); its Hessian couples the node's motion along t with u.
            let e = match terms.slides[i] {
                Some(slide) => material_offset(&x[i], u[i], &self.predicted[i], &slide),
                None => x[i] - self.predicted[i],
            };
            let mut r = -e * inertia;
            if let Some(hold) = terms.holds[i] {
                let k = hold_matrix(&hold);
                block += k;
                r += k * (hold.place_mm.cast::<f64>() - x[i]);
            }
            diag[i].fixed_view_mut::<3, 3>(0, 0).copy_from(&block);
            rhs[i].fixed_rows_mut::<3>(0).copy_from(&r);
            if let Some(slide) = terms.slides[i].filter(|_| self.sliding::<D>(i)) {
                let t = slide.tangent;
                rhs[i][3] = inertia * t.dot(&e) - slide.friction_n;
                let b = &mut diag[i];
                for r in 0..3 {
                    b[(r, 3)] = -inertia * t[r];
                    b[(3, r)] = -inertia * t[r];
                }
                b[(3, 3)] = inertia;
            }
        }
        for s in 0..n - 1 {
            let d = x[s + 1] - x[s];
            let len = d.norm();
            let k = f64::from(terms.stiffness_n_per_mm[s]);
            let rest = u[s + 1] - u[s];
            let (dir, geometric) = if len > 1e-12 {
                (d / len, (1.0 - rest / len).max(0.0))
            } else {
                (V64::x(), 0.0)
            };
            // C = |d| - (u_b - u_a): its gradient in (x_a, u_a) and (x_b, u_b).
            let ja = wide_v(&-dir, if self.sliding::<D>(s) { 1.0 } else { 0.0 });
            let jb = wide_v(&dir, if self.sliding::<D>(s + 1) { -1.0 } else { 0.0 });
            let across = wide(&((M64::identity() - dir * dir.transpose()) * (geometric * k)));
            let c = len - rest;
            if terms.free(s) {
                diag[s] += ja * ja.transpose() * k + across;
                rhs[s] -= ja * (k * c);
            }
            if terms.free(s + 1) {
                diag[s + 1] += jb * jb.transpose() * k + across;
                rhs[s + 1] -= jb * (k * c);
            }
            off[s] = if terms.free(s) && terms.free(s + 1) {
                ja * jb.transpose() * k - across
            } else {
                SMatrix::<f64, D, D>::zeros()
            };
        }
        let kb = f64::from(terms.bend_n_per_mm);
        if kb > 0.0 {
            for i in 1..n - 1 {
                chord[i] = (x[i + 1] - x[i - 1])
                    .try_normalize(1e-12)
                    .unwrap_or_else(V64::zeros);
                let across = M64::identity() - chord[i] * chord[i].transpose();
                let c = across * (x[i] - (x[i - 1] + x[i + 1]) * 0.5);
                let block = wide(&(across * kb));
                if terms.free(i) {
                    diag[i] += block;
                    rhs[i] -= wide_v(&(c * kb), 0.0);
                }
                for j in [i - 1, i + 1] {
                    if terms.free(j) {
                        // A quarter of the hinge's stiffness, and a quarter more for the coupling between the
                        // two neighbours, moved onto the diagonal (module doc).
                        diag[j] += block * 0.5;
                        rhs[j] += wide_v(&(c * (0.5 * kb)), 0.0);
                    }
                }
                if terms.free(i) && terms.free(i - 1) {
                    off[i - 1] -= block * 0.5;
                }
                if terms.free(i) && terms.free(i + 1) {
                    off[i] -= block * 0.5;
                }
            }
        }
    }
}

/// Solve a symmetric block-tridiagonal system in place: `diag` (overwritten with the eliminated blocks'
/// inverses), `off[i]` the block `A_{i,i+1}` (`A_{i+1,i}` its transpose), `rhs` overwritten with the solution.
/// Elimination: `D_i = A_ii - A_{i,i-1} D_{i-1}^-1 A_{i-1,i}`, `y_i = r_i - A_{i,i-1} D_{i-1}^-1 y_{i-1}`; then
/// back substitution, `x_i = D_i^-1 (y_i - A_{i,i+1} x_{i+1})`. None when a block is singular.
fn eliminate<const D: usize>(
    diag: &mut [SMatrix<f64, D, D>],
    off: &[SMatrix<f64, D, D>],
    rhs: &mut [SVector<f64, D>],
) -> Option<()> {
    let n = diag.len();
    for i in 0..n {
        if i > 0 {
            let o = off[i - 1];
            let l = o.transpose() * diag[i - 1];
            diag[i] -= l * o;
            let carried = l * rhs[i - 1];
            rhs[i] -= carried;
        }
        diag[i] = diag[i].try_inverse()?;
    }
    for i in (0..n).rev() {
        let ahead = if i + 1 < n {
            off[i] * rhs[i + 1]
        } else {
            SVector::<f64, D>::zeros()
        };
        rhs[i] = diag[i] * (rhs[i] - ahead);
    }
    Some(())
}

/// How far a sliding node's material is from where inertia takes it: `(x - p) - t (u - u_p)`, mm.
fn material_offset(x: &V64, u: f64, predicted: &V64, slide: &NodeSlide) -> V64 {
    (x - predicted) - slide.tangent * (u - slide.predicted_u_mm)
}

/// A hold's spring matrix: `across (I - t t^T) + along t t^T`, N/mm.
fn hold_matrix(hold: &NodeHold) -> M64 {
    let t = hold.direction.cast::<f64>();
    let ttt = t * t.transpose();
    (M64::identity() - ttt) * f64::from(hold.across_n_per_mm) + ttt * f64::from(hold.along_n_per_mm)
}

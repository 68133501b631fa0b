//! The thread chain's implicit step, solved by Newton's method in the nodes' positions, in f64.
//!
//! Owns: [`PositionSolve`] (its scratch) and [`ChainTerms`] (what the step's energy is made of). Each substep
//! minimises `sum m_i |x_i - p_i|^2 / (2 h^2)` (inertia about the prediction `p`) plus each segment's spring
//! `k (|d| - l)^2 / 2` (`k = EA / l`), the holds' springs (`NodeHold`) and the hinges' bending `k_b |c|^2 / 2`
//! (`c` a node's offset from its neighbours' midpoint across their chord).
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

use nalgebra::{Matrix3, Vector3};

use super::NodeHold;
use crate::tissue::MM_PER_M;

/// A position in f64, mm.
pub type V64 = Vector3<f64>;
type M64 = Matrix3<f64>;

/// A Newton step moving no node further than this has converged, mm.
pub const CONVERGED_MM: f64 = 1e-7;
/// Times a Newton step is halved when it would not lower the energy.
const LINE_SEARCH_HALVINGS: usize = 8;

/// What the step's energy is made of: per node the inverse mass (1/kg; 0: held, it does not move) and the hold
/// (if any), per segment the rest length (mm) and the spring (N/mm), and the hinges' bending stiffness (N/mm).
#[derive(Debug, Clone, Copy)]
pub struct ChainTerms<'a> {
    /// Per node, 1/kg.
    pub inverse_mass_per_kg: &'a [f32],
    /// Per node.
    pub holds: &'a [Option<NodeHold>],
    /// Per segment, mm.
    pub rest_mm: &'a [f32],
    /// Per segment, N/mm.
    pub stiffness_n_per_mm: &'a [f32],
    /// Every hinge's, N/mm (0: none).
    pub bend_n_per_mm: f32,
}

/// The solver's scratch for a chain of `n` nodes.
#[derive(Debug, Clone)]
pub struct PositionSolve {
    before: Vec<V64>,
    block_inv: Vec<M64>,
    block_off: Vec<M64>,
    rhs: Vec<V64>,
    chord: Vec<V64>,
}

impl PositionSolve {
    /// Scratch for `n` nodes (allocates).
    pub fn new(n: usize) -> Self {
        Self {
            before: vec![V64::zeros(); n],
            block_inv: vec![M64::zeros(); n],
            block_off: vec![M64::zeros(); n.saturating_sub(1)],
            rhs: vec![V64::zeros(); n],
            chord: vec![V64::zeros(); n],
        }
    }

    /// Solve the step of `h_s` from the prediction `predicted` (also the start: `x` is set to it first), at most
    /// `max_newton` Newton steps. Returns the steps taken. No allocation.
    pub fn solve(
        &mut self,
        x: &mut [V64],
        predicted: &[V64],
        terms: &ChainTerms,
        h_s: f64,
        max_newton: usize,
    ) -> usize {
        x.copy_from_slice(predicted);
        for k in 0..max_newton {
            match self.newton_step(x, predicted, terms, h_s) {
                Some(moved) if moved > CONVERGED_MM => {}
                _ => return k + 1,
            }
        }
        max_newton
    }

    /// One Newton step with its line search. The largest move of a node (None: nothing moved).
    fn newton_step(
        &mut self,
        x: &mut [V64],
        predicted: &[V64],
        terms: &ChainTerms,
        h_s: f64,
    ) -> Option<f64> {
        let n = x.len();
        let h2 = h_s * h_s;
        let free = |i: usize| terms.inverse_mass_per_kg[i] != 0.0;
        for i in 0..n {
            if !free(i) {
                self.block_inv[i] = M64::identity();
                self.rhs[i] = V64::zeros();
                continue;
            }
            // m / h^2 in N/mm (kg/s^2 is N/m).
            let inertia = 1.0 / (f64::from(terms.inverse_mass_per_kg[i]) * MM_PER_M as f64 * h2);
            self.block_inv[i] = M64::identity() * inertia;
            self.rhs[i] = (predicted[i] - x[i]) * inertia;
            if let Some(hold) = terms.holds[i] {
                let k = hold_matrix(&hold);
                self.block_inv[i] += k;
                self.rhs[i] += k * (hold.place_mm.cast::<f64>() - x[i]);
            }
        }
        for s in 0..n - 1 {
            let d = x[s + 1] - x[s];
            let len = d.norm();
            let k = f64::from(terms.stiffness_n_per_mm[s]);
            let rest = f64::from(terms.rest_mm[s]);
            let (dir, geometric) = if len > 1e-12 {
                (d / len, (1.0 - rest / len).max(0.0))
            } else {
                (V64::x(), 0.0)
            };
            let nnt = dir * dir.transpose();
            let block = (nnt + (M64::identity() - nnt) * geometric) * k;
            // The spring pulls s + 1 toward s, and s toward s + 1, with k (len - l).
            let pull = dir * (k * (len - rest));
            if free(s) {
                self.block_inv[s] += block;
                self.rhs[s] += pull;
            }
            if free(s + 1) {
                self.block_inv[s + 1] += block;
                self.rhs[s + 1] -= pull;
            }
            self.block_off[s] = if free(s) && free(s + 1) {
                -block
            } else {
                M64::zeros()
            };
        }
        let kb = f64::from(terms.bend_n_per_mm);
        if kb > 0.0 {
            for i in 1..n - 1 {
                self.chord[i] = (x[i + 1] - x[i - 1])
                    .try_normalize(1e-12)
                    .unwrap_or_else(V64::zeros);
                let chord = self.chord[i];
                let across = M64::identity() - chord * chord.transpose();
                let c = across * (x[i] - (x[i - 1] + x[i + 1]) * 0.5);
                let block = across * kb;
                if free(i) {
                    self.block_inv[i] += block;
                    self.rhs[i] -= c * kb;
                }
                for j in [i - 1, i + 1] {
                    if free(j) {
                        // A quarter of the hinge's stiffness, and a quarter more for the coupling between the
                        // two neighbours, moved onto the diagonal (module doc).
                        self.block_inv[j] += block * 0.5;
                        self.rhs[j] += c * (0.5 * kb);
                    }
                }
                if free(i) && free(i - 1) {
                    self.block_off[i - 1] -= block * 0.5;
                }
                if free(i) && free(i + 1) {
                    self.block_off[i] -= block * 0.5;
                }
            }
        }
        // Elimination: D_i = A_ii - A_{i,i-1} D_{i-1}^-1 A_{i-1,i}, y_i = r_i - A_{i,i-1} D_{i-1}^-1 y_{i-1}; then
        // back substitution, dx_i = D_i^-1 (y_i - A_{i,i+1} dx_{i+1}), into rhs.
        for i in 0..n {
            if i > 0 {
                let off = self.block_off[i - 1];
                let l = off * self.block_inv[i - 1];
                self.block_inv[i] -= l * off;
                let carried = l * self.rhs[i - 1];
                self.rhs[i] -= carried;
            }
            self.block_inv[i] = self.block_inv[i].try_inverse()?;
        }
        for i in (0..n).rev() {
            let ahead = if i + 1 < n {
                self.block_off[i] * self.rhs[i + 1]
            } else {
                V64::zeros()
            };
            self.rhs[i] = self.block_inv[i] * (self.rhs[i] - ahead);
        }
        if !self.rhs.iter().all(|d| d.iter().all(|c| c.is_finite())) {
            return None;
        }
        let largest = self.rhs.iter().map(|d| d.norm()).fold(0.0, f64::max);
        let energy_before = self.energy(x, predicted, terms, h_s);
        self.before.copy_from_slice(x);
        let mut scale = 1.0;
        for _ in 0..=LINE_SEARCH_HALVINGS {
            for i in (0..n).filter(|&i| free(i)) {
                x[i] = self.before[i] + self.rhs[i] * scale;
            }
            if self.energy(x, predicted, terms, h_s) <= energy_before {
                return Some(largest * scale);
            }
            scale *= 0.5;
        }
        x.copy_from_slice(&self.before);
        None
    }

    /// The step's energy at `x` (the hinges' chords as frozen for this Newton step), N mm.
    fn energy(&self, x: &[V64], predicted: &[V64], terms: &ChainTerms, h_s: f64) -> f64 {
        let h2 = h_s * h_s;
        let mut e = 0.0;
        for i in 0..x.len() {
            let w = f64::from(terms.inverse_mass_per_kg[i]);
            if w == 0.0 {
                continue;
            }
            e += 0.5 / (w * MM_PER_M as f64 * h2) * (x[i] - predicted[i]).norm_squared();
            if let Some(hold) = terms.holds[i] {
                let off = x[i] - hold.place_mm.cast::<f64>();
                e += 0.5 * off.dot(&(hold_matrix(&hold) * off));
            }
        }
        for s in 0..x.len() - 1 {
            let stretch = (x[s + 1] - x[s]).norm() - f64::from(terms.rest_mm[s]);
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

/// A hold's spring matrix: `across (I - t t^T) + along t t^T`, N/mm.
fn hold_matrix(hold: &NodeHold) -> M64 {
    let t = hold.direction.cast::<f64>();
    let ttt = t * t.transpose();
    (M64::identity() - ttt) * f64::from(hold.across_n_per_mm) + ttt * f64::from(hold.along_n_per_mm)
}

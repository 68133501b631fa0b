//! Anti-divergence: detect a step that blew up, so the caller can restore the saved state and retry it
//! with the step halved.
//!
//! A step has diverged when any position or velocity is non-finite, any node moves faster than
//! `max_speed_mm_s`, or any node is farther from its rest position than `max_displacement_mm` (the object's
//! rest diagonal by default: tissue that has moved farther than its own size is not tissue any more). The
//! guard owns the saved copy; saving and checking are O(nodes), allocation-free once built.

use super::{MassSpringModel, TissueState, Vec3};

/// Default speed above which a node is taken as diverging, mm/s (10 m/s: ten times a fast hand).
pub const DEFAULT_MAX_SPEED_MM_S: f32 = 10_000.0;

/// A saved state and the limits that define divergence.
#[derive(Debug, Clone)]
pub struct DivergenceGuard {
    saved_positions_mm: Vec<Vec3>,
    saved_velocities_mm_s: Vec<Vec3>,
    max_speed_mm_s: f32,
    max_displacement_mm: f32,
}

impl DivergenceGuard {
    /// A guard for `model` with the default limits.
    pub fn new(model: &MassSpringModel) -> Self {
        let rest = model.rest_positions_mm();
        let (mut lo, mut hi) = (Vec3::repeat(f32::INFINITY), Vec3::repeat(f32::NEG_INFINITY));
        for p in rest {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let diagonal = if rest.is_empty() {
            1.0
        } else {
            (hi - lo).norm().max(1.0)
        };
        Self {
            saved_positions_mm: rest.to_vec(),
            saved_velocities_mm_s: vec![Vec3::zeros(); rest.len()],
            max_speed_mm_s: DEFAULT_MAX_SPEED_MM_S,
            max_displacement_mm: diagonal,
        }
    }

    /// Override the limits.
    pub fn with_limits(mut self, max_speed_mm_s: f32, max_displacement_mm: f32) -> Self {
        self.max_speed_mm_s = max_speed_mm_s;
        self.max_displacement_mm = max_displacement_mm;
        self
    }

    /// Remember `state` (no allocation once sized).
    pub fn save(&mut self, state: &TissueState) {
        self.saved_positions_mm.clear();
        self.saved_positions_mm
            .extend_from_slice(&state.positions_mm);
        self.saved_velocities_mm_s.clear();
        self.saved_velocities_mm_s
            .extend_from_slice(&state.velocities_mm_s);
    }

    /// Put the saved positions and velocities back.
    pub fn restore(&self, state: &mut TissueState) {
        state.positions_mm.copy_from_slice(&self.saved_positions_mm);
        state
            .velocities_mm_s
            .copy_from_slice(&self.saved_velocities_mm_s);
    }

    /// Whether `state` has diverged. Never panics; NaN counts as diverged.
    pub fn diverged(&self, model: &MassSpringModel, state: &TissueState) -> bool {
        let speed2 = self.max_speed_mm_s * self.max_speed_mm_s;
        let displacement2 = self.max_displacement_mm * self.max_displacement_mm;
        let mut worst_speed2 = 0.0f32;
        let mut worst_displacement2 = 0.0f32;
        for ((x, v), rest) in state
            .positions_mm
            .iter()
            .zip(&state.velocities_mm_s)
            .zip(model.rest_positions_mm())
        {
            // max() drops NaN; a plain sum carries it, so check finiteness on sums below.
            worst_speed2 = worst_speed2.max(v.norm_squared());
            worst_displacement2 = worst_displacement2.max((x - rest).norm_squared());
        }
        !state.is_finite() || worst_speed2 > speed2 || worst_displacement2 > displacement2
    }
}

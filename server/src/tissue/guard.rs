//! Anti-divergence: detect a step that blew up, so the caller can restore the saved state and retry it
//! with the step halved.
//!
//! Two tests, two verdicts ([`Verdict`]):
//! - **Broken** ([`DivergenceGuard::assess`]): a non-finite position or velocity, a node farther from rest
//!   than `max_displacement_mm` (the object's rest diagonal by default: tissue that moved farther than its own
//!   size is not tissue any more), or a node faster than `max_speed_mm_s` (100 m/s). Retried; reset to rest if
//!   it persists at the smallest step.
//! - **Growing** ([`energy_grew`]): the mechanical energy (kinetic + potential) rose by more than
//!   [`ENERGY_GROWTH`] times what it was plus the work the tools could have done (the caller's allowance).
//!   A damped elastic body cannot gain energy on its own; an unstable mode multiplies it every substep, so
//!   it is caught within a tick, before the saved state is contaminated. Retried; if it persists at the
//!   smallest step the result is kept, never reset.
//!
//! Speed-growth tests were tried first and failed: within a tick, legitimate motion trades potential for
//! kinetic energy, so a node's speed can grow tenfold, while a step just above the bound grows the energy
//! only a little per tick. A fixed energy floor failed too: too small and a tool's work trips it, too large
//! and a small object's instability creeps under it; hence the work allowance from the tools' own motion.
//! Saving and checking are O(nodes), the energy O(springs); allocation-free once built.

use super::{MassSpringModel, TissueState, Vec3};

/// Default speed above which a node is taken as diverging, mm/s (100 m/s: a hundred times a fast hand).
pub const DEFAULT_MAX_SPEED_MM_S: f32 = 100_000.0;

/// Largest factor by which the mechanical energy may grow over one tick beyond the work allowance.
pub const ENERGY_GROWTH: f64 = 1.5;

/// Energy any tick may add regardless of the tools, N mm (= mJ): rounding noise of a settled object.
pub const ENERGY_FLOOR_N_MM: f64 = 1e-6;

/// Whether the energy rose from `before` to `after` (N mm) by more than the growth factor, the floor and the
/// `allowance_n_mm` of work done from outside. Non-finite `after` counts as growth. The growth is a share of
/// the energy's size: under gravity the mechanical energy is negative once an object hangs below its rest
/// shape, and a settling object's energy then falls further below zero, which is not growth.
pub fn energy_grew(before_n_mm: f64, after_n_mm: f64, allowance_n_mm: f64) -> bool {
    // `before + (ENERGY_GROWTH - 1) |before|`, written so a non-negative `before` gives the same bits as ever.
    let grown_n_mm = if before_n_mm >= 0.0 {
        ENERGY_GROWTH * before_n_mm
    } else {
        (2.0 - ENERGY_GROWTH) * before_n_mm
    };
    !after_n_mm.is_finite() || after_n_mm > grown_n_mm + allowance_n_mm + ENERGY_FLOOR_N_MM
}

/// The most work one active tool can have done on the tissue in a step, N mm: four times its force limit times
/// how far it moved (its size when it has just become active), so a tool's real work never looks like
/// divergence.
pub fn tool_work_allowance_n_mm(max_force_n: f32, travel_mm: f32) -> f64 {
    4.0 * f64::from(max_force_n) * f64::from(travel_mm)
}

/// How far a tool moved in a step for [`tool_work_allowance_n_mm`], mm: from its last position if it was active
/// then, else its reach (it has just come in).
pub fn tool_travel_mm(
    was_active: bool,
    position_mm: &Vec3,
    last_position_mm: &Vec3,
    reach_mm: f32,
) -> f32 {
    if was_active {
        (position_mm - last_position_mm).norm()
    } else {
        reach_mm
    }
}

/// What [`DivergenceGuard::assess`] measured on one object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    /// Non-finite, too fast or too far from rest.
    pub broken: bool,
    /// Kinetic plus potential energy (springs, anchors, volume terms, gravity; potential from rest, floored at
    /// zero: gravity can make it negative), N mm.
    pub energy_n_mm: f64,
}

/// A tick's verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Nothing wrong.
    Fine,
    /// Energy grew beyond what the step can explain: retry smaller, keep the result if it persists.
    Growing,
    /// Non-finite, or beyond the absolute limits: retry smaller, reset to rest if it persists.
    Broken,
}

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

    /// The same guard with another displacement limit, mm: an object whose nodes honestly travel further than
    /// its rest size (a thread fixed at one end swings through twice its length) is judged against what it can
    /// reach. A non-finite or non-positive limit keeps the default.
    pub fn with_max_displacement_mm(mut self, limit_mm: f32) -> Self {
        if limit_mm.is_finite() && limit_mm > 0.0 {
            self.max_displacement_mm = limit_mm;
        }
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

    /// Remember only the nodes in `nodes` (the caller guarantees no other node changes before
    /// [`Self::restore_nodes`] with the same list). No allocation; never panics.
    pub fn save_nodes(&mut self, state: &TissueState, nodes: &[u32]) {
        self.saved_positions_mm.clear();
        self.saved_velocities_mm_s.clear();
        for &i in nodes {
            if let (Some(x), Some(v)) = (
                state.positions_mm.get(i as usize),
                state.velocities_mm_s.get(i as usize),
            ) {
                self.saved_positions_mm.push(*x);
                self.saved_velocities_mm_s.push(*v);
            }
        }
    }

    /// Put back what [`Self::save_nodes`] saved for the same `nodes`. No allocation; never panics.
    pub fn restore_nodes(&self, state: &mut TissueState, nodes: &[u32]) {
        for ((&i, x), v) in nodes
            .iter()
            .zip(&self.saved_positions_mm)
            .zip(&self.saved_velocities_mm_s)
        {
            if let (Some(px), Some(pv)) = (
                state.positions_mm.get_mut(i as usize),
                state.velocities_mm_s.get_mut(i as usize),
            ) {
                *px = *x;
                *pv = *v;
            }
        }
    }

    /// The absolute tests of [`Self::assess`] over `nodes` only (region tracking: nothing else moved).
    /// O(nodes), never panics.
    pub fn broken_nodes(
        &self,
        model: &MassSpringModel,
        state: &TissueState,
        nodes: &[u32],
    ) -> bool {
        let speed2 = self.max_speed_mm_s * self.max_speed_mm_s;
        let displacement2 = self.max_displacement_mm * self.max_displacement_mm;
        let rest = model.rest_positions_mm();
        let mut sum = 0.0f32;
        for &i in nodes {
            let i = i as usize;
            let (Some(x), Some(v), Some(r)) = (
                state.positions_mm.get(i),
                state.velocities_mm_s.get(i),
                rest.get(i),
            ) else {
                continue;
            };
            let (s2, d2) = (v.norm_squared(), (x - r).norm_squared());
            if s2 > speed2 || d2 > displacement2 {
                return true;
            }
            sum += s2 + d2;
        }
        !sum.is_finite()
    }

    /// The absolute tests and the energy in one pass over the nodes plus one over the springs and volume
    /// terms. Never panics; no allocation.
    pub fn assess(&self, model: &MassSpringModel, state: &TissueState) -> Assessment {
        let k_anchor = model.anchor_stiffness_n_per_mm();
        let g = model.gravity_mm_per_s2() / super::MM_PER_M;
        let (mut worst_speed2, mut worst_displacement2) = (0.0f32, 0.0f32);
        let (mut finite, mut kinetic_2, mut nodes) = (0.0f32, 0.0f32, 0.0f32);
        for ((((x, v), rest), m), w) in state
            .positions_mm
            .iter()
            .zip(&state.velocities_mm_s)
            .zip(model.rest_positions_mm())
            .zip(model.mass_kg())
            .zip(model.accel_per_force())
        {
            let d = x - rest;
            let (v2, d2) = (v.norm_squared(), d.norm_squared());
            worst_speed2 = worst_speed2.max(v2);
            worst_displacement2 = worst_displacement2.max(d2);
            finite += v2 + d2;
            if *w > 0.0 {
                kinetic_2 += m * v2;
                nodes += 0.5 * k_anchor * d2 - m * g.dot(&d);
            }
        }
        let broken = !finite.is_finite()
            || worst_speed2 > self.max_speed_mm_s * self.max_speed_mm_s
            || worst_displacement2 > self.max_displacement_mm * self.max_displacement_mm;
        if broken {
            return Assessment {
                broken,
                energy_n_mm: f64::INFINITY,
            };
        }
        // kg (mm/s)^2 = 1e-3 N mm.
        let kinetic = 0.5e-3 * f64::from(kinetic_2);
        // Gravity's potential counts with its sign: an object falling under gravity trades it for kinetic
        // energy, which is not growth (`energy_grew` measures growth against the energy's size).
        let potential = f64::from(nodes) + model.elastic_energy_n_mm(&state.positions_mm);
        Assessment {
            broken,
            energy_n_mm: kinetic + potential,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn growth_is_a_share_of_the_energy_whatever_its_sign() {
        // Positive energy: as ever, 1.5 times plus the floor.
        assert!(!energy_grew(1.0, 1.5, 0.0));
        assert!(energy_grew(1.0, 1.6, 0.0));
        // A hanging object's energy is negative (gravity's potential): settling lower is not growth, and
        // gaining half its size is.
        assert!(!energy_grew(-1.0, -1.2, 0.0));
        assert!(!energy_grew(-1.0, -0.5, 0.0));
        assert!(energy_grew(-1.0, -0.4, 0.0));
        // The allowance and the floor apply on both sides of zero.
        assert!(!energy_grew(-1.0, 0.5, 1.0));
        assert!(!energy_grew(0.0, 0.5 * ENERGY_FLOOR_N_MM, 0.0));
        assert!(energy_grew(-1.0, f64::NAN, 0.0));
    }
}

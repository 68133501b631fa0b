//! The guarded step every object takes, every tick or multi-rate: integrate the step in substeps, judge it with
//! the guard, and retry it with halved substeps while it is broken or gains energy nothing put in.
//!
//! Owns: [`MAX_HALVINGS`], the [`Stepped`] seam (what a stepper does: integrate, judge, restore) and
//! [`step_guarded`], the one retry loop that the tick ([`crate::sim::Sim::step`]) and a multi-rate object's job
//! ([`crate::multirate::StepJob::run`]) share.
//!
//! Must not: save the state (the caller saves what it may restore: every node, or a region's), or contain a
//! failure (reset to rest, release grasps): what containment means is the caller's, told by
//! [`GuardedStep::gave_up`].

use super::guard::{Verdict, energy_grew};

/// Times the anti-divergence guard may halve a step's substeps (down to 1/16 of the planned one) before it gives
/// up: a broken object is then reset to rest, a merely energetic one kept.
pub const MAX_HALVINGS: u32 = 4;

/// What [`step_guarded`] drives.
pub trait Stepped {
    /// Integrate `substeps` substeps of `h_s` seconds each.
    fn integrate(&mut self, h_s: f32, substeps: u32);
    /// Whether anything is broken, and the mechanical energy now, N mm.
    fn judge(&mut self) -> (bool, f64);
    /// Put back the state saved before the step.
    fn restore(&mut self);
}

/// What one guarded step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardedStep {
    /// The verdict on the last try: [`Verdict::Fine`] unless the guard gave up at the smallest substeps.
    pub verdict: Verdict,
    /// Times the step was restored and retried with halved substeps.
    pub retries: u32,
    /// Substeps integrated over every try.
    pub substeps: u32,
    /// The mechanical energy after the last try, N mm.
    pub energy_n_mm: f64,
}

impl GuardedStep {
    /// Still wrong at 1/2^[`MAX_HALVINGS`] of the planned substeps: the caller contains it.
    pub fn gave_up(&self) -> bool {
        self.verdict != Verdict::Fine
    }
}

/// Step `dt_s` in `planned` substeps, judged against `energy_before_n_mm` plus the tools' `allowance_n_mm`;
/// restore and retry with twice the substeps while the verdict is not fine, at most [`MAX_HALVINGS`] times.
/// Allocates nothing itself; never panics.
pub fn step_guarded(
    stepper: &mut impl Stepped,
    dt_s: f32,
    planned: u32,
    energy_before_n_mm: f64,
    allowance_n_mm: f64,
) -> GuardedStep {
    let mut step = GuardedStep {
        verdict: Verdict::Fine,
        retries: 0,
        substeps: 0,
        energy_n_mm: energy_before_n_mm,
    };
    loop {
        let substeps = planned << step.retries;
        stepper.integrate(dt_s / substeps as f32, substeps);
        step.substeps += substeps;
        let (broken, energy_n_mm) = stepper.judge();
        step.energy_n_mm = energy_n_mm;
        step.verdict = if broken {
            Verdict::Broken
        } else if energy_grew(energy_before_n_mm, energy_n_mm, allowance_n_mm) {
            Verdict::Growing
        } else {
            Verdict::Fine
        };
        if step.verdict == Verdict::Fine || step.retries == MAX_HALVINGS {
            return step;
        }
        stepper.restore();
        step.retries += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stepper whose energy after a try is a function of its substep (an unstable scheme above `stable_h`).
    struct Scheme {
        stable_h_s: f32,
        broken_always: bool,
        tries: Vec<(f32, u32)>,
        restores: u32,
        last_h_s: f32,
    }

    impl Stepped for Scheme {
        fn integrate(&mut self, h_s: f32, substeps: u32) {
            self.tries.push((h_s, substeps));
            self.last_h_s = h_s;
        }
        fn judge(&mut self) -> (bool, f64) {
            let energy = if self.last_h_s > self.stable_h_s {
                100.0
            } else {
                1.0
            };
            (self.broken_always, energy)
        }
        fn restore(&mut self) {
            self.restores += 1;
        }
    }

    fn scheme(stable_h_s: f32, broken_always: bool) -> Scheme {
        Scheme {
            stable_h_s,
            broken_always,
            tries: Vec::new(),
            restores: 0,
            last_h_s: 0.0,
        }
    }

    #[test]
    fn a_stable_step_runs_once_as_planned() {
        let mut s = scheme(1.0, false);
        let step = step_guarded(&mut s, 0.001, 2, 1.0, 0.0);
        assert_eq!(s.tries, vec![(0.0005, 2)]);
        assert_eq!(
            (step.verdict, step.retries, step.substeps, s.restores),
            (Verdict::Fine, 0, 2, 0)
        );
    }

    #[test]
    fn a_growing_step_is_halved_until_it_is_fine() {
        // Stable at a quarter of the planned substep: two retries.
        let mut s = scheme(0.001 / 4.0, false);
        let step = step_guarded(&mut s, 0.001, 1, 1.0, 0.0);
        assert_eq!(
            s.tries.iter().map(|t| t.1).collect::<Vec<_>>(),
            vec![1, 2, 4]
        );
        assert_eq!(
            (step.verdict, step.retries, step.substeps, s.restores),
            (Verdict::Fine, 2, 7, 2)
        );
        assert_eq!(step.energy_n_mm, 1.0);
        assert!(!step.gave_up());
    }

    #[test]
    fn a_step_still_broken_at_the_smallest_substep_gives_up_without_a_last_restore() {
        let mut s = scheme(1.0, true);
        let step = step_guarded(&mut s, 0.001, 1, 1.0, 0.0);
        assert_eq!(step.retries, MAX_HALVINGS);
        assert_eq!(s.tries.len() as u32, MAX_HALVINGS + 1);
        assert_eq!(
            s.restores, MAX_HALVINGS,
            "the last try is left for the caller to contain"
        );
        assert_eq!(step.verdict, Verdict::Broken);
        assert!(step.gave_up());
    }

    #[test]
    fn the_tools_allowance_excuses_their_work() {
        let mut s = scheme(0.0, false);
        let step = step_guarded(&mut s, 0.001, 1, 1.0, 200.0);
        assert_eq!((step.verdict, step.retries), (Verdict::Fine, 0));
    }
}

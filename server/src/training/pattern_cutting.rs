//! Scoring FLS's pattern-cutting task (`kind = "pattern-cutting"`) from the sim's reading of the cut
//! ([`crate::sim::StepReport::pattern_cut`], `tissue::pattern_cut`).
//!
//! Rules, as MISTELS scores the task (Derossis, Fried et al.; the FLS manual skills test): the task is done when
//! the marked circle comes free of the clipped sheet, before the cutoff time (the exercise's time limit; 300 s in
//! the shipped world, as in MISTELS). The penalty is the percentage area of deviation: the area cut on the wrong
//! side of the band between the two marked circles, as a percentage of the pattern's area. The task's points are
//! the cutoff less the time taken less the penalty, at least 0; a task not done by the cutoff scores 0 (MISTELS
//! normalises these points by a reference group's, which is not published with the task: the report gives the
//! raw points, and the exercise's 0-100 score is those points as a share of the cutoff). Any deviation is an
//! error: the task passes done with none.
//!
//! Owns: [`PatternJudge`] (the reading kept, frozen when the circle comes free) and [`PatternCutScore`].
//! Must not: allocate, or read a clock.

use serde::{Deserialize, Serialize};

use crate::tissue::pattern_cut::PatternCutReading;

/// How the pattern was cut.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PatternCutScore {
    /// The circle came free of the sheet.
    pub freed: bool,
    /// Area of the piece cut out beyond the outer circle, mm^2 (cut too wide).
    pub outside_band_mm2: f64,
    /// Area of the sheet left within the inner circle, mm^2 (cut into the pattern).
    pub inside_band_mm2: f64,
    /// Their sum as a percentage of the pattern's area: the MISTELS penalty.
    pub deviation_pct: f64,
    /// MISTELS points: the cutoff less the time less the penalty, at least 0 (0 if not freed in time).
    pub mistels_points: f64,
}

/// The pattern's cut as last read, frozen once the circle came free.
#[derive(Debug, Clone, Copy, Default)]
pub struct PatternJudge {
    reading: Option<PatternCutReading>,
    freed: bool,
}

impl PatternJudge {
    /// The reading after a tick (None changes nothing). Returns true on the tick the circle first comes free;
    /// after that the reading is kept as it was then.
    pub fn on_reading(&mut self, reading: Option<PatternCutReading>) -> bool {
        let Some(reading) = reading else {
            return false;
        };
        if self.freed {
            return false;
        }
        self.reading = Some(reading);
        self.freed = reading.freed;
        self.freed
    }

    /// The circle came free.
    pub fn freed(&self) -> bool {
        self.freed
    }

    /// The score with the task taking `time_s` against `cutoff_s`, done in time or not (`completed`).
    pub fn score(&self, time_s: f64, cutoff_s: f64, completed: bool) -> PatternCutScore {
        let reading = self.reading.unwrap_or_default();
        let deviation_pct = f64::from(reading.deviation_pct());
        PatternCutScore {
            freed: self.freed,
            outside_band_mm2: f64::from(reading.outside_band_mm2),
            inside_band_mm2: f64::from(reading.inside_band_mm2),
            deviation_pct,
            mistels_points: if completed {
                (cutoff_s - time_s - deviation_pct).max(0.0)
            } else {
                0.0
            },
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::scene::{ExerciseKind, ExerciseSpec, PatternSpec};
    use crate::training::{EventKind, ExerciseRun, SessionEvent, ToolActivity};

    fn reading(freed: bool, outside: f32) -> Option<PatternCutReading> {
        Some(PatternCutReading {
            freed,
            outside_band_mm2: outside,
            inside_band_mm2: 0.0,
            pattern_area_mm2: 1000.0,
        })
    }

    #[test]
    fn points_are_the_cutoff_less_the_time_less_the_penalty_and_the_reading_freezes_when_the_circle_comes_free()
     {
        let mut judge = PatternJudge::default();
        assert!(!judge.on_reading(reading(false, 10.0)));
        assert!(!judge.on_reading(None));
        assert!(judge.on_reading(reading(true, 50.0)));
        // Cutting on after the circle came free changes nothing.
        assert!(!judge.on_reading(reading(true, 400.0)));
        let s = judge.score(100.0, 300.0, true);
        assert!(s.freed);
        assert_eq!(s.deviation_pct, 5.0);
        assert_eq!(s.mistels_points, 195.0);
        assert_eq!(judge.score(299.0, 300.0, true).mistels_points, 0.0);
        assert_eq!(judge.score(100.0, 300.0, false).mistels_points, 0.0);
    }

    fn pattern_run(limit_s: f64) -> ExerciseRun {
        let spec = ExerciseSpec {
            name: "pattern".into(),
            kind: ExerciseKind::PatternCutting,
            time_limit_s: limit_s,
            depth_limit_mm: None,
            targets: Vec::new(),
            samples: Vec::new(),
            wound: None,
            knot: false,
            pattern: Some(PatternSpec {
                object: 0,
                centre_mm: [0.0; 3],
                inner_radius_mm: 9.5,
                outer_radius_mm: 10.5,
            }),
        };
        ExerciseRun::new(spec, 1, 0.001)
    }

    fn joined(run: &mut ExerciseRun, tick: u64) {
        let event = SessionEvent {
            tick,
            tool: 0,
            kind: EventKind::Joined,
        };
        run.on_event(&event, &ToolActivity::default());
    }

    #[test]
    fn the_run_is_done_when_the_circle_comes_free_on_the_clock_and_not_before_it_starts_or_after_it_ends()
     {
        // Freed before anyone drives a tool: not done (a world loaded cut is not a trainee's cut).
        let mut run = pattern_run(1.0);
        run.on_pattern_cut(5, reading(true, 0.0));
        assert!(!run.live().completed);
        // Freed 0.5 s after the clock started, on the band: done, passed, 100 x (1 - 0.5) / 1 points.
        let mut run = pattern_run(1.0);
        joined(&mut run, 0);
        run.on_pattern_cut(300, reading(false, 0.0));
        run.on_pattern_cut(499, reading(true, 0.0));
        let score = run.score();
        assert!(score.completed && score.passed, "{score:?}");
        assert_eq!((score.targets_hit, score.targets_total), (1, 1));
        assert!((score.score - 50.0).abs() < 1e-9, "{score:?}");
        assert_eq!(run.live().score, score.score);
        // Freed with 5% of the pattern cut outside the band: done, not passed, the penalty off the points.
        let mut run = pattern_run(100.0);
        joined(&mut run, 0);
        run.on_pattern_cut(999, reading(true, 50.0));
        let score = run.score();
        assert!(score.completed && !score.passed, "{score:?}");
        assert!((score.pattern.unwrap().mistels_points - (100.0 - 1.0 - 5.0)).abs() < 1e-9);
        // Freed after the time ran out: not done, no points.
        let mut run = pattern_run(1.0);
        joined(&mut run, 0);
        run.on_tick(1001, &[ToolActivity::default()]);
        run.on_pattern_cut(1002, reading(true, 0.0));
        let score = run.score();
        assert!(
            !score.completed && score.timed_out && score.score == 0.0,
            "{score:?}"
        );
    }
}

//! Running and scoring a training exercise ([`crate::scene::ExerciseSpec`]) from the session's events.
//!
//! Owns: [`ExerciseRun`] (the live state: which target is next, the clock, the errors) and [`ExerciseScore`].
//!
//! Rules. The clock starts at the first tick a device drives a tool. Each touch (a debounced
//! [`EventKind::ContactBegin`]) is judged where the tool's centre is at that tick, across the surface (in the
//! world's x-y plane: targets lie on surfaces facing up, as on the pad):
//! - within the next target's radius, by the tool it names (or any tool if it names none): a hit, and the
//!   exercise moves to the following target; the last hit completes it;
//! - within the next target's radius by another tool: a **wrong-tool** error;
//! - anywhere else: an **off-target** error (tissue touched where it should not be).
//!
//! A suture exercise judges punctures instead of touches ([`EventKind::Puncture`], where the needle went in on
//! the tissue at rest, [`ToolActivity::newest_hole_rest_mm`], in 3-D: marks lie on any face): a puncture within
//! the next mark's radius hits it (the entry mark, then the exit mark), by the tool it names if it names one
//! (else a wrong-tool error); any other puncture (the bites through the wound's faces between the marks, or one
//! off its mark) is not judged, and touches are not judged at all. `mean_distance_mm` is then the mm off the
//! marks. A suture exercise that names its wound also keeps the wound's latest gap (each tick's
//! [`crate::sim::StepReport::wound_gap_mm`], through [`ExerciseRun::on_wound_gap`]); it passes only closed to
//! [`SUTURE_GAP_LIMIT_MM`] or less. Every suture exercise reads the knot its thread ties (each tick's
//! [`ToolActivity::knot`], any tool's: one thread, read by the tools that draw it) and counts each knot that came
//! undone (read, then no knot); one tied off ([`ExerciseSpec::knot`]) passes only with a secure knot read at the
//! end (two throws or more that can alternate hands: a square knot, a surgeon's knot; a half knot or a granny
//! is not), and each knot that came undone is a **knot-undone** error (FLS fails a knot that comes apart; its
//! slipping, which needs the knot to lock, is not read yet).
//!
//! A stiffness-ranking exercise has samples instead of targets: every touch over a sample (inside its rest
//! extent across the surface) is that sample's latest, and a touch over none is off target. The answer is the
//! order of the samples' last touches (softest first); each pair of samples in the right order scores, and the
//! report lists every pair with its stiffness ratio (success against the stiffness difference).
//!
//! While a touch that hit lasts, its depth is tracked: how far the tool's centre went below where it was when the
//! touch began. Past the exercise's depth limit, the touch is a **too-deep** error (once per touch). When the time
//! limit passes before the last hit, the remaining targets are missed. Score: 100 points shared among the targets
//! hit, minus 10 per error, at least 0; passed means every target hit and no error.
//!
//! Must not: allocate after construction (it can run on the sim thread) or read a clock.

use serde::{Deserialize, Serialize};

use super::events::{EventKind, SessionEvent, ToolActivity};
use super::knot_score::{KnotScore, secure_knot};
use super::pattern_cutting::{PatternCutScore, PatternJudge};
use crate::scene::{ExerciseKind, ExerciseSpec, SUTURE_GAP_LIMIT_MM};
use crate::tissue::pattern_cut::PatternCutReading;

/// Points lost per error.
pub const POINTS_PER_ERROR: f64 = 10.0;

/// One hit target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TargetHit {
    /// Target index.
    pub target: usize,
    /// The tool that hit it.
    pub tool: usize,
    /// When, s from the exercise's start.
    pub at_s: f64,
    /// Distance from the mark across the surface, mm.
    pub distance_mm: f64,
    /// Deepest press during the touch, mm.
    pub max_depth_mm: f64,
}

/// Errors by kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ExerciseErrors {
    /// The next target touched by a tool it does not name.
    pub wrong_tool: u32,
    /// Tissue touched away from the next target.
    pub off_target: u32,
    /// A hit pressed deeper than the limit.
    pub too_deep: u32,
    /// A knot read in the thread came undone (an exercise tied off).
    #[serde(default)]
    pub knot_undone: u32,
}

impl ExerciseErrors {
    /// All errors.
    pub fn total(&self) -> u32 {
        self.wrong_tool + self.off_target + self.too_deep + self.knot_undone
    }
}

/// One pair of samples in a ranking: did the trainee put the softer first?
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankedPair {
    /// The softer sample's name.
    pub softer: String,
    /// The firmer sample's name.
    pub firmer: String,
    /// Firmer over softer stiffness.
    pub stiffness_ratio: f64,
    /// Ranked right.
    pub correct: bool,
}

/// A ranking's answer against the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankingResult {
    /// The samples in the order of their last touches (touched ones only).
    pub answer: Vec<String>,
    /// The samples from softest to firmest.
    pub truth: Vec<String>,
    /// Every pair of samples with distinct stiffness.
    pub pairs: Vec<RankedPair>,
    /// Touches per sample, in world order.
    pub touches: Vec<u32>,
}

/// How an exercise went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExerciseScore {
    /// The exercise's name.
    pub name: String,
    /// Its kind.
    pub kind: ExerciseKind,
    /// Every target hit in time.
    pub completed: bool,
    /// Completed with no error.
    pub passed: bool,
    /// 0-100.
    pub score: f64,
    /// From the start to the last hit (or to the limit, or to the end of the session), s.
    pub time_s: f64,
    /// The time limit passed first.
    pub timed_out: bool,
    /// Targets hit, of `targets_total` (a ranking: pairs ranked right, of all pairs).
    pub targets_hit: usize,
    /// Targets in the exercise (a ranking: pairs of samples).
    pub targets_total: usize,
    /// Errors.
    pub errors: ExerciseErrors,
    /// Mean distance of the hits from their marks, mm (0 without hits).
    pub mean_distance_mm: f64,
    /// Deepest press at a hit, mm.
    pub max_depth_mm: f64,
    /// The hits, in order.
    pub hits: Vec<TargetHit>,
    /// A stiffness ranking's answer.
    pub ranking: Option<RankingResult>,
    /// A suture exercise's wound: its gap when last told, mm (None: it names no wound).
    #[serde(default)]
    pub wound_gap_mm: Option<f64>,
    /// A suture exercise's knot (None: another kind).
    #[serde(default)]
    pub knot: Option<KnotScore>,
    /// A pattern-cutting exercise's cut (None: another kind).
    #[serde(default)]
    pub pattern: Option<PatternCutScore>,
}

/// The running score, without the lists (no allocation: read on the sim thread).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LiveScore {
    /// Every target hit (a ranking: every sample answered).
    pub completed: bool,
    /// 0-100 so far.
    pub score: f64,
    /// Targets hit (a ranking: pairs in the right order so far).
    pub hits: usize,
    /// Targets (a ranking: pairs).
    pub total: usize,
    /// Errors so far.
    pub errors: ExerciseErrors,
    /// Time on the exercise's clock, s.
    pub time_s: f64,
    /// The time limit passed.
    pub timed_out: bool,
}

/// A touch in progress that hit a target: its tool's starting height and the deepest it went.
#[derive(Debug, Clone, Copy)]
struct OpenTouch {
    hit: usize,
    start_z_mm: f32,
    flagged: bool,
}

/// The live state of an exercise.
#[derive(Debug, Clone)]
pub struct ExerciseRun {
    spec: ExerciseSpec,
    dt_s: f64,
    started_tick: Option<u64>,
    finished_tick: Option<u64>,
    timed_out_tick: Option<u64>,
    last_tick: u64,
    hits: Vec<TargetHit>,
    errors: ExerciseErrors,
    open: Vec<Option<OpenTouch>>,
    /// Per sample (ranking): the tick of its last touch, and its touches.
    last_touch: Vec<Option<u64>>,
    touches: Vec<u32>,
    /// The wound's gap when last told, mm (a suture exercise that names its wound).
    wound_gap_mm: Option<f32>,
    /// The knot read on the last tick (a suture exercise), and the knots that came undone.
    knot: Option<crate::interaction::suture::Throws>,
    knots_undone: u32,
    /// A pattern-cutting exercise's cut.
    pattern: PatternJudge,
}

impl ExerciseRun {
    /// A run of `spec` over `tools` tools, ticks of `dt_s`.
    pub fn new(spec: ExerciseSpec, tools: usize, dt_s: f64) -> Self {
        let hits = Vec::with_capacity(spec.targets.len());
        let samples = spec.samples.len();
        Self {
            last_touch: vec![None; samples],
            touches: vec![0; samples],
            spec,
            dt_s,
            started_tick: None,
            finished_tick: None,
            timed_out_tick: None,
            last_tick: 0,
            hits,
            errors: ExerciseErrors::default(),
            open: vec![None; tools],
            wound_gap_mm: None,
            knot: None,
            knots_undone: 0,
            pattern: PatternJudge::default(),
        }
    }

    /// The pattern's cut after tick `tick` (a pattern-cutting exercise; None changes nothing): the exercise is
    /// done on the tick the circle comes free, if the clock runs and the time has not passed.
    pub fn on_pattern_cut(&mut self, tick: u64, reading: Option<PatternCutReading>) {
        if self.spec.kind != ExerciseKind::PatternCutting
            || self.started_tick.is_none()
            || self.finished_tick.is_some()
            || self.timed_out_tick.is_some()
        {
            return;
        }
        if self.pattern.on_reading(reading) {
            self.finished_tick = Some(tick);
        }
    }

    /// The wound's gap after a tick, mm (None, or a non-finite one, changes nothing). Kept only for a suture
    /// exercise that names its wound.
    pub fn on_wound_gap(&mut self, gap_mm: Option<f32>) {
        if self.spec.kind == ExerciseKind::Suture
            && self.spec.wound.is_some()
            && let Some(gap) = gap_mm.filter(|g| g.is_finite())
        {
            self.wound_gap_mm = Some(gap);
        }
    }

    /// The exercise.
    pub fn spec(&self) -> &ExerciseSpec {
        &self.spec
    }

    /// The target to touch next (None when done or out of time).
    pub fn next_target(&self) -> Option<usize> {
        (self.finished_tick.is_none() && self.timed_out_tick.is_none())
            .then_some(self.hits.len())
            .filter(|&n| n < self.spec.targets.len())
    }

    fn elapsed_s(&self, tick: u64) -> f64 {
        self.started_tick.map_or(0.0, |start| {
            (tick.saturating_sub(start) + 1) as f64 * self.dt_s
        })
    }

    /// An event on tool `event.tool`, whose activity this tick is `activity`.
    pub fn on_event(&mut self, event: &SessionEvent, activity: &ToolActivity) {
        let tool = usize::from(event.tool);
        match event.kind {
            EventKind::Joined if self.started_tick.is_none() => {
                self.started_tick = Some(event.tick)
            }
            EventKind::ContactBegin if self.spec.kind != ExerciseKind::Suture => {
                self.touch(event.tick, tool, activity)
            }
            EventKind::Puncture if self.spec.kind == ExerciseKind::Suture => {
                self.puncture(event.tick, tool, activity)
            }
            EventKind::ContactEnd | EventKind::Left => {
                if let Some(slot) = self.open.get_mut(tool) {
                    *slot = None;
                }
            }
            _ => {}
        }
    }

    fn touch(&mut self, tick: u64, tool: usize, activity: &ToolActivity) {
        if self.spec.kind == ExerciseKind::StiffnessRanking {
            self.touch_sample(tick, activity);
            return;
        }
        let Some(next) = self.next_target() else {
            return;
        };
        let target = &self.spec.targets[next];
        let [x, y, z] = activity.tool_world_mm;
        let distance_mm = (f64::from(x - target.at_mm[0])).hypot(f64::from(y - target.at_mm[1]));
        if distance_mm > f64::from(target.radius_mm) {
            self.errors.off_target += 1;
            return;
        }
        if target.tool.is_some_and(|t| t != tool) {
            self.errors.wrong_tool += 1;
            return;
        }
        let at_s = self.elapsed_s(tick);
        self.hits.push(TargetHit {
            target: next,
            tool,
            at_s,
            distance_mm,
            max_depth_mm: 0.0,
        });
        if let Some(slot) = self.open.get_mut(tool) {
            *slot = Some(OpenTouch {
                hit: self.hits.len() - 1,
                start_z_mm: z,
                flagged: false,
            });
        }
        if self.hits.len() == self.spec.targets.len() {
            self.finished_tick = Some(tick);
        }
    }

    fn puncture(&mut self, tick: u64, tool: usize, activity: &ToolActivity) {
        let (Some(next), Some(at)) = (self.next_target(), activity.newest_hole_rest_mm) else {
            return;
        };
        let target = &self.spec.targets[next];
        let distance_mm = at
            .iter()
            .zip(&target.at_mm)
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        if distance_mm.is_nan() || distance_mm > f64::from(target.radius_mm) {
            return;
        }
        if target.tool.is_some_and(|t| t != tool) {
            self.errors.wrong_tool += 1;
            return;
        }
        self.hits.push(TargetHit {
            target: next,
            tool,
            at_s: self.elapsed_s(tick),
            distance_mm,
            max_depth_mm: 0.0,
        });
        if self.hits.len() == self.spec.targets.len() {
            self.finished_tick = Some(tick);
        }
    }

    fn touch_sample(&mut self, tick: u64, activity: &ToolActivity) {
        if self.timed_out_tick.is_some() {
            return;
        }
        let [x, y, _] = activity.tool_world_mm;
        let over = self.spec.samples.iter().position(|s| {
            (s.min_xy_mm[0]..=s.max_xy_mm[0]).contains(&x)
                && (s.min_xy_mm[1]..=s.max_xy_mm[1]).contains(&y)
        });
        match over {
            Some(s) => {
                self.last_touch[s] = Some(tick);
                self.touches[s] += 1;
            }
            None => self.errors.off_target += 1,
        }
    }

    fn ranking(&self) -> RankingResult {
        let samples = &self.spec.samples;
        let mut answer: Vec<usize> = (0..samples.len())
            .filter(|&s| self.last_touch[s].is_some())
            .collect();
        answer.sort_by_key(|&s| self.last_touch[s]);
        let mut truth: Vec<usize> = (0..samples.len()).collect();
        truth.sort_by(|&a, &b| {
            samples[a]
                .stiffness_n_per_mm
                .total_cmp(&samples[b].stiffness_n_per_mm)
        });
        let mut pairs = Vec::new();
        for (i, &soft) in truth.iter().enumerate() {
            for &firm in &truth[i + 1..] {
                let (ks, kf) = (
                    samples[soft].stiffness_n_per_mm,
                    samples[firm].stiffness_n_per_mm,
                );
                if kf <= ks {
                    continue;
                }
                let correct = matches!(
                    (self.last_touch[soft], self.last_touch[firm]),
                    (Some(a), Some(b)) if a < b
                );
                pairs.push(RankedPair {
                    softer: samples[soft].name.clone(),
                    firmer: samples[firm].name.clone(),
                    stiffness_ratio: f64::from(kf / ks),
                    correct,
                });
            }
        }
        RankingResult {
            answer: answer.iter().map(|&s| samples[s].name.clone()).collect(),
            truth: truth.iter().map(|&s| samples[s].name.clone()).collect(),
            pairs,
            touches: self.touches.clone(),
        }
    }

    /// The end of tick `tick`, with every tool's activity: depths of open touches, and the clock.
    pub fn on_tick(&mut self, tick: u64, activities: &[ToolActivity]) {
        self.last_tick = tick;
        if self.spec.kind == ExerciseKind::Suture {
            let knot = activities.iter().find_map(|a| a.knot);
            if self.knot.is_some() && knot.is_none() {
                self.knots_undone += 1;
                if self.spec.knot {
                    self.errors.knot_undone += 1;
                }
            }
            self.knot = knot;
        }
        let limit = self.spec.depth_limit_mm;
        for (slot, activity) in self.open.iter_mut().zip(activities) {
            let Some(open) = slot else { continue };
            let depth_mm = f64::from(open.start_z_mm - activity.tool_world_mm[2]);
            if let Some(hit) = self.hits.get_mut(open.hit)
                && depth_mm.is_finite()
                && depth_mm > hit.max_depth_mm
            {
                hit.max_depth_mm = depth_mm;
            }
            if let Some(limit) = limit
                && !open.flagged
                && depth_mm > f64::from(limit)
            {
                open.flagged = true;
                self.errors.too_deep += 1;
            }
        }
        let open_ended = self.spec.kind == ExerciseKind::StiffnessRanking;
        if (self.finished_tick.is_none() || open_ended)
            && self.timed_out_tick.is_none()
            && self.started_tick.is_some()
            && self.elapsed_s(tick) > self.spec.time_limit_s
        {
            self.timed_out_tick = Some(tick);
        }
    }

    /// The running score, without allocating.
    pub fn live(&self) -> LiveScore {
        let (hits, total, completed) = if self.spec.kind == ExerciseKind::StiffnessRanking {
            let samples = &self.spec.samples;
            let (mut right, mut pairs) = (0, 0);
            for (a, sa) in samples.iter().enumerate() {
                for (b, sb) in samples.iter().enumerate() {
                    if sa.stiffness_n_per_mm < sb.stiffness_n_per_mm {
                        pairs += 1;
                        if matches!((self.last_touch[a], self.last_touch[b]), (Some(x), Some(y)) if x < y)
                        {
                            right += 1;
                        }
                    }
                }
            }
            (right, pairs, self.last_touch.iter().all(Option::is_some))
        } else if self.spec.kind == ExerciseKind::PatternCutting {
            let freed = self.pattern.freed();
            (usize::from(freed), 1, freed)
        } else {
            (
                self.hits.len(),
                self.spec.targets.len(),
                self.finished_tick.is_some(),
            )
        };
        let errors = self.errors;
        let timed_out = self.timed_out_tick.is_some();
        let end_tick = self
            .finished_tick
            .or(self.timed_out_tick)
            .unwrap_or(self.last_tick);
        let time_s = if timed_out && !completed {
            self.spec.time_limit_s
        } else {
            self.elapsed_s(end_tick)
        };
        LiveScore {
            completed,
            score: match self.spec.kind {
                ExerciseKind::PatternCutting => self.pattern_points(time_s, completed).1,
                _ => (100.0 * hits as f64 / total.max(1) as f64
                    - POINTS_PER_ERROR * f64::from(errors.total()))
                .max(0.0),
            },
            hits,
            total,
            errors,
            time_s,
            timed_out,
        }
    }

    /// A pattern-cutting exercise's cut taking `time_s`, and its 0-100 score: the MISTELS points as a share
    /// of the cutoff (`training::pattern_cutting`).
    fn pattern_points(&self, time_s: f64, completed: bool) -> (PatternCutScore, f64) {
        let cutoff_s = self.spec.time_limit_s;
        let cut = self.pattern.score(time_s, cutoff_s, completed);
        (cut, 100.0 * cut.mistels_points / cutoff_s)
    }

    /// The score so far.
    pub fn score(&self) -> ExerciseScore {
        let ranking = (self.spec.kind == ExerciseKind::StiffnessRanking).then(|| self.ranking());
        let (total, hit, completed) = match &ranking {
            // A ranking is complete when every sample has an answer; its "targets" are the pairs.
            Some(r) => (
                r.pairs.len(),
                r.pairs.iter().filter(|p| p.correct).count(),
                r.answer.len() == self.spec.samples.len(),
            ),
            None if self.spec.kind == ExerciseKind::PatternCutting => {
                let freed = self.pattern.freed();
                (1, usize::from(freed), self.finished_tick.is_some())
            }
            None => (
                self.spec.targets.len(),
                self.hits.len(),
                self.finished_tick.is_some(),
            ),
        };
        let errors = self.errors;
        let end_tick = self
            .finished_tick
            .or(self.timed_out_tick)
            .unwrap_or(self.last_tick);
        let time_s = if self.timed_out_tick.is_some() && (!completed || ranking.is_some()) {
            self.spec.time_limit_s
        } else {
            self.elapsed_s(end_tick)
        };
        let pattern = (self.spec.kind == ExerciseKind::PatternCutting)
            .then(|| self.pattern_points(time_s, completed));
        let score = match &pattern {
            Some((_, score)) => *score,
            None => (100.0 * hit as f64 / total.max(1) as f64
                - POINTS_PER_ERROR * f64::from(errors.total()))
            .max(0.0),
        };
        // A pattern cut anywhere outside its band is cut with an error (MISTELS: "any deviation").
        let on_band = pattern
            .as_ref()
            .is_none_or(|(cut, _)| cut.deviation_pct == 0.0);
        // A suture exercise's wound must be closed (a wound named but never told of is not), and one tied off
        // must end with a secure knot.
        let closed = self.spec.wound.is_none()
            || self.wound_gap_mm.is_some_and(|g| g <= SUTURE_GAP_LIMIT_MM);
        let knot = (self.spec.kind == ExerciseKind::Suture).then(|| KnotScore {
            name: self.knot.map(|t| t.name()),
            throws: self.knot.map_or([0; 4], |t| {
                [t.single_right, t.single_left, t.double_right, t.double_left]
            }),
            secure: self.knot.as_ref().is_some_and(secure_knot),
            undone: self.knots_undone,
        });
        let tied = !self.spec.knot || knot.as_ref().is_some_and(|k| k.secure);
        ExerciseScore {
            name: self.spec.name.clone(),
            kind: self.spec.kind,
            completed,
            passed: completed && errors.total() == 0 && hit == total && closed && tied && on_band,
            score,
            time_s,
            timed_out: self.timed_out_tick.is_some() && (!completed || ranking.is_some()),
            targets_hit: hit,
            targets_total: total,
            errors,
            mean_distance_mm: if !self.hits.is_empty() {
                self.hits.iter().map(|h| h.distance_mm).sum::<f64>() / self.hits.len() as f64
            } else {
                0.0
            },
            max_depth_mm: self.hits.iter().map(|h| h.max_depth_mm).fold(0.0, f64::max),
            hits: self.hits.clone(),
            ranking,
            wound_gap_mm: self.wound_gap_mm.map(f64::from),
            knot,
            pattern: pattern.map(|(cut, _)| cut),
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests;

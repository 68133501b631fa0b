//! The training layer's view of a session: per tool, an [`EventDetector`], a [`SkillMachine`] and
//! [`ParticipantMetrics`], fed from each tick's outputs. The same code runs behind a replay (`sinew report`)
//! and can run on the sim thread (no allocation).
//!
//! Owns: [`SessionObserver`], [`TickView`] (what one tick shows it).

use crate::sim::{StepReport, ToolOutput};

use super::events::{EventDetector, SessionEvent, ToolActivity};
use super::exercise::ExerciseRun;
use super::metrics::{MetricsConfig, ParticipantMetrics};
use super::skill_state::{SkillMachine, SkillState, Transition};

/// What one server tick shows the training layer.
#[derive(Debug, Clone, Copy)]
pub struct TickView<'a> {
    /// Tick index.
    pub tick: u64,
    /// Per tool: a device drove it this tick.
    pub active: &'a [bool],
    /// Per tool: the tick's output.
    pub outputs: &'a [ToolOutput],
    /// The step's report (object resets).
    pub step: &'a StepReport,
}

/// Per tool: events, skill state and metrics.
#[derive(Debug, Clone)]
pub struct SessionObserver {
    detectors: Vec<EventDetector>,
    machines: Vec<SkillMachine>,
    metrics: Vec<ParticipantMetrics>,
    activity: Vec<ToolActivity>,
    exercise: Option<ExerciseRun>,
}

/// One participant as the training layer sees it, live (a copy: no allocation).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LiveTraining {
    /// Current skill state.
    pub state: SkillState,
    /// Touches so far.
    pub contacts: u64,
    /// Time in contact, s.
    pub contact_time_s: f64,
    /// Instrument tip path, mm.
    pub path_length_mm: f64,
    /// Largest force on the tool, N.
    pub peak_force_n: f64,
    /// Force above the harm threshold, integrated, N s.
    pub harm_n_s: f64,
}

impl SessionObserver {
    /// An observer of `tools` tools.
    pub fn new(tools: usize, config: MetricsConfig) -> Self {
        Self {
            detectors: (0..tools)
                .map(|t| {
                    EventDetector::new(t.min(usize::from(u8::MAX)) as u8, config.harm_threshold_n)
                })
                .collect(),
            machines: vec![SkillMachine::new(); tools],
            metrics: vec![ParticipantMetrics::new(config); tools],
            activity: vec![ToolActivity::default(); tools],
            exercise: None,
        }
    }

    /// Also run and score `exercise`.
    pub fn with_exercise(mut self, exercise: ExerciseRun) -> Self {
        self.exercise = Some(exercise);
        self
    }

    /// The exercise being run, if any.
    pub fn exercise(&self) -> Option<&ExerciseRun> {
        self.exercise.as_ref()
    }

    /// One tick: its events and state changes go to the sinks (transitions with their tool index).
    pub fn observe(
        &mut self,
        view: &TickView<'_>,
        mut on_event: impl FnMut(&SessionEvent),
        mut on_transition: impl FnMut(u8, &Transition),
    ) {
        let fault = view.step.faults > 0;
        for (t, ((detector, machine), metrics)) in self
            .detectors
            .iter_mut()
            .zip(&mut self.machines)
            .zip(&mut self.metrics)
            .enumerate()
        {
            let active = view.active.get(t).copied().unwrap_or(false);
            let activity = view
                .outputs
                .get(t)
                .map_or_else(ToolActivity::default, |out| {
                    ToolActivity::from_output(active, out)
                });
            let tool = t as u8;
            let exercise = &mut self.exercise;
            detector.detect(view.tick, &activity, fault, |event| {
                on_event(&event);
                metrics.on_event(&event);
                machine.on_event(&event, |tr| on_transition(tool, &tr));
                if let Some(run) = exercise.as_mut() {
                    run.on_event(&event, &activity);
                }
            });
            machine.on_tick(view.tick, activity.force_n, activity.thread_pull_n, |tr| {
                on_transition(tool, &tr)
            });
            metrics.push(view.tick, &activity);
            self.activity[t] = activity;
        }
        if let Some(run) = self.exercise.as_mut() {
            run.on_tick(view.tick, &self.activity);
            run.on_wound_gap(view.step.wound_gap_mm);
            run.on_pattern_cut(view.tick, view.step.pattern_cut);
        }
    }

    /// Tool `t`'s activity on the last tick observed.
    pub fn activity(&self, t: usize) -> Option<&ToolActivity> {
        self.activity.get(t)
    }

    /// Participant `t` as an instructor sees it now (a copy: no allocation).
    pub fn live(&self, t: usize) -> Option<LiveTraining> {
        let (machine, metrics) = (self.machine(t)?, self.metrics(t)?);
        let m = metrics.summary();
        Some(LiveTraining {
            state: machine.state(),
            contacts: m.contacts,
            contact_time_s: m.contact_time_s,
            path_length_mm: m.path_length_mm,
            peak_force_n: m.peak_force_n,
            harm_n_s: m.harm_n_s,
        })
    }

    /// Participant `t`'s skill-state machine.
    pub fn machine(&self, t: usize) -> Option<&SkillMachine> {
        self.machines.get(t)
    }

    /// Tool `t`'s metrics.
    pub fn metrics(&self, t: usize) -> Option<&ParticipantMetrics> {
        self.metrics.get(t)
    }
}

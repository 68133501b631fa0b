//! Surgical skill states: a finite-state machine per participant, driven by [`SessionEvent`]s, that records
//! its transitions and the time spent in each state (the suturing prototype's scoring model, in general form).
//!
//! Owns: [`SkillState`], [`Transition`], [`SkillMachine`].
//!
//! The machine keeps the conditions the events set (driving, near tissue, touching, grasping, cutting,
//! burning) and derives its state from them by priority: not driven is idle; burning is cauterizing; cutting
//! is cutting; grasping is pulling while the force on the jaws exceeds the pull threshold, else grasping; after
//! jaws open on tissue the machine is releasing until the tool leaves the tissue or the release time passes;
//! touching is contact; near is approach; else idle.
//!
//! Suturing (after the haptic suturing prototype's states: grasp needle, puncture, push through, pull
//! through; and the tighten) refines it, below burning and cutting and above the rest: a tool drawing
//! a thread that runs through holes (its needle through and out of the tissue, or the thread in its jaws) is
//! tightening while the thread pulls it harder than the tighten threshold, else pulling through; a needle
//! running through tissue is pushing through; a needle's tip pressing a surface is the puncture; a thread
//! held with no holes is grasping; a needle held, touching nothing, is needle grasped (in place of approach
//! and idle). The hand-off: jaws holding a needle they took while it ran through tissue are regrasping (above
//! pushing through: they draw it out on the far side), and a tool that let its needle go in the tissue is
//! releasing it until jaws take it (below everything it does with its jaws meanwhile). The knot waits for the
//! knot (`docs/suturing.md`).
//!
//! Must not: allocate (it can run on the sim thread; transitions go to a caller's sink) or read a clock.

use serde::{Deserialize, Serialize};

use super::events::{EventKind, SessionEvent};

/// A surgical state.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
pub enum SkillState {
    /// No device drives the tool, or it is far from tissue.
    #[default]
    Idle,
    /// Tissue lies within the tool's look-ahead.
    Approach,
    /// The tool touches tissue (probing, pressing).
    Contact,
    /// Jaws hold tissue.
    Grasping,
    /// Jaws hold tissue and pull on it (force above the pull threshold).
    Pulling,
    /// A sharp edge cuts.
    Cutting,
    /// An active tip burns.
    Cauterizing,
    /// Jaws opened on tissue; the tool has not left it yet.
    Releasing,
    /// Jaws hold a suture needle, touching nothing.
    NeedleGrasped,
    /// The needle's tip presses a surface, before it punctures.
    Puncture,
    /// The needle runs through tissue.
    PushThrough,
    /// The tool let its needle go in the tissue; no jaws hold it yet.
    Release,
    /// Jaws took the needle while it ran through tissue, and draw it on (through its exit).
    Regrasp,
    /// The thread the tool draws runs through the tissue, pulling it less than the tighten threshold.
    PullThrough,
    /// The thread pulls the tool harder than the tighten threshold: the stitch is drawn tight.
    Tighten,
}

impl SkillState {
    /// Every state, in declaration order.
    pub const ALL: [SkillState; 15] = [
        SkillState::Idle,
        SkillState::Approach,
        SkillState::Contact,
        SkillState::Grasping,
        SkillState::Pulling,
        SkillState::Cutting,
        SkillState::Cauterizing,
        SkillState::Releasing,
        SkillState::NeedleGrasped,
        SkillState::Puncture,
        SkillState::PushThrough,
        SkillState::Release,
        SkillState::Regrasp,
        SkillState::PullThrough,
        SkillState::Tighten,
    ];

    /// Its index in [`SkillState::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            SkillState::Idle => "idle",
            SkillState::Approach => "approach",
            SkillState::Contact => "contact",
            SkillState::Grasping => "grasping",
            SkillState::Pulling => "pulling",
            SkillState::Cutting => "cutting",
            SkillState::Cauterizing => "cauterizing",
            SkillState::Releasing => "releasing",
            SkillState::NeedleGrasped => "needle_grasped",
            SkillState::Puncture => "puncture",
            SkillState::PushThrough => "push_through",
            SkillState::Release => "release",
            SkillState::Regrasp => "regrasp",
            SkillState::PullThrough => "pull_through",
            SkillState::Tighten => "tighten",
        }
    }
}

/// A change of state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Transition {
    /// Tick of the event that caused it.
    pub tick: u64,
    /// From.
    pub from: SkillState,
    /// To.
    pub to: SkillState,
}

/// One participant's state machine.
#[derive(Debug, Clone)]
pub struct SkillMachine {
    state: SkillState,
    active: bool,
    near: bool,
    contact: bool,
    grasping: bool,
    pulling: bool,
    cutting: bool,
    burning: bool,
    needle_held: bool,
    needle_pressing: bool,
    needle_in_tissue: bool,
    needle_released: bool,
    needle_regrasped: bool,
    thread_held: bool,
    thread_through: bool,
    tightening: bool,
    tighten_threshold_n: f32,
    /// Releasing lasts until this tick (exclusive), or until contact ends.
    release_until_tick: u64,
    release_ticks: u64,
    pull_threshold_n: f32,
    ticks_in: [u64; SkillState::ALL.len()],
    transitions: u64,
}

impl SkillMachine {
    /// Releasing lasts at most this long after the jaws open, ticks of 1 ms.
    pub const DEFAULT_RELEASE_TICKS: u64 = 500;
    /// Force on grasping jaws above which the tissue is being pulled, N.
    pub const DEFAULT_PULL_THRESHOLD_N: f32 = 0.5;
    /// A thread's pull on the tool drawing it above which the stitch is being tightened, N (surgeons close
    /// skin with 0.5-3.2 N; Capek et al. 2012).
    pub const DEFAULT_TIGHTEN_THRESHOLD_N: f32 = 1.0;

    /// An idle machine with the default release time and pull threshold.
    pub fn new() -> Self {
        Self::with(Self::DEFAULT_RELEASE_TICKS, Self::DEFAULT_PULL_THRESHOLD_N)
    }

    /// An idle machine: releasing lasts at most `release_ticks`; grasping jaws pull above `pull_threshold_n`.
    pub fn with(release_ticks: u64, pull_threshold_n: f32) -> Self {
        Self {
            state: SkillState::Idle,
            active: false,
            near: false,
            contact: false,
            grasping: false,
            pulling: false,
            cutting: false,
            burning: false,
            needle_held: false,
            needle_pressing: false,
            needle_in_tissue: false,
            needle_released: false,
            needle_regrasped: false,
            thread_held: false,
            thread_through: false,
            tightening: false,
            tighten_threshold_n: Self::DEFAULT_TIGHTEN_THRESHOLD_N,
            release_until_tick: 0,
            release_ticks,
            pull_threshold_n,
            ticks_in: [0; SkillState::ALL.len()],
            transitions: 0,
        }
    }

    /// The current state.
    pub fn state(&self) -> SkillState {
        self.state
    }

    /// Ticks spent in each state, indexed by [`SkillState::index`].
    pub fn ticks_in(&self) -> &[u64; SkillState::ALL.len()] {
        &self.ticks_in
    }

    /// Transitions so far.
    pub fn transitions(&self) -> u64 {
        self.transitions
    }

    /// Apply one event; a change of state goes to `sink`.
    pub fn on_event(&mut self, event: &SessionEvent, sink: impl FnMut(Transition)) {
        match event.kind {
            EventKind::Joined => self.active = true,
            EventKind::Left => {
                self.active = false;
                self.near = false;
                self.contact = false;
                self.grasping = false;
                self.pulling = false;
                self.cutting = false;
                self.burning = false;
                self.needle_held = false;
                self.needle_pressing = false;
                self.needle_in_tissue = false;
                self.needle_released = false;
                self.needle_regrasped = false;
                self.thread_held = false;
                self.thread_through = false;
                self.tightening = false;
                self.release_until_tick = 0;
            }
            EventKind::ApproachBegin => self.near = true,
            EventKind::ApproachEnd => self.near = false,
            EventKind::ContactBegin => self.contact = true,
            EventKind::ContactEnd => {
                self.contact = false;
                self.release_until_tick = 0;
            }
            EventKind::GraspBegin => {
                self.grasping = true;
                self.release_until_tick = 0;
            }
            EventKind::GraspEnd => {
                self.grasping = false;
                self.pulling = false;
                self.release_until_tick = event.tick.saturating_add(self.release_ticks);
            }
            EventKind::CutBegin => self.cutting = true,
            EventKind::CutEnd => self.cutting = false,
            EventKind::BurnBegin => self.burning = true,
            EventKind::BurnEnd => self.burning = false,
            EventKind::NeedleGraspBegin => self.needle_held = true,
            EventKind::NeedleGraspEnd => self.needle_held = false,
            EventKind::NeedleReleaseBegin => self.needle_released = true,
            EventKind::NeedleReleaseEnd => self.needle_released = false,
            EventKind::NeedleRegraspBegin => self.needle_regrasped = true,
            EventKind::NeedleRegraspEnd => self.needle_regrasped = false,
            EventKind::NeedlePressBegin => self.needle_pressing = true,
            EventKind::NeedlePressEnd => self.needle_pressing = false,
            EventKind::PushThroughBegin => self.needle_in_tissue = true,
            EventKind::PushThroughEnd => self.needle_in_tissue = false,
            EventKind::ThreadGraspBegin => self.thread_held = true,
            EventKind::ThreadGraspEnd => self.thread_held = false,
            EventKind::ThreadThroughBegin => self.thread_through = true,
            EventKind::ThreadThroughEnd => {
                self.thread_through = false;
                self.tightening = false;
            }
            EventKind::Puncture
            | EventKind::HarmBegin
            | EventKind::HarmEnd
            | EventKind::TissueFault
            // The knot is scored, not a state of the hand (yet).
            | EventKind::KnotTied
            | EventKind::KnotUndone => {}
        }
        self.settle(event.tick, sink);
    }

    /// The end of tick `tick`: the force on the tool then (for pulling) and the thread's pull on it (for
    /// tightening), counted in the state it ends in. Call after the tick's events.
    pub fn on_tick(
        &mut self,
        tick: u64,
        force_n: f32,
        thread_pull_n: f32,
        sink: impl FnMut(Transition),
    ) {
        self.pulling = self.grasping && force_n > self.pull_threshold_n;
        self.tightening = self.thread_through && thread_pull_n > self.tighten_threshold_n;
        self.settle(tick, sink);
        self.ticks_in[self.state.index()] += 1;
    }

    fn settle(&mut self, tick: u64, mut sink: impl FnMut(Transition)) {
        let next = self.derive(tick);
        if next != self.state {
            sink(Transition {
                tick,
                from: self.state,
                to: next,
            });
            self.transitions += 1;
            self.state = next;
        }
    }

    /// The state the conditions give at `tick`, by priority.
    fn derive(&self, tick: u64) -> SkillState {
        if !self.active {
            SkillState::Idle
        } else if self.burning {
            SkillState::Cauterizing
        } else if self.cutting {
            SkillState::Cutting
        } else if let Some(suturing) = self.suturing() {
            suturing
        } else if self.grasping && self.pulling {
            SkillState::Pulling
        } else if self.grasping {
            SkillState::Grasping
        } else if self.contact && tick < self.release_until_tick {
            SkillState::Releasing
        } else if self.contact {
            SkillState::Contact
        } else if self.needle_held {
            SkillState::NeedleGrasped
        } else if self.near {
            SkillState::Approach
        } else {
            SkillState::Idle
        }
    }

    /// The suturing state the conditions give, if any, by priority (module doc).
    fn suturing(&self) -> Option<SkillState> {
        let draws_thread = self.thread_held || (self.needle_held && !self.needle_in_tissue);
        if draws_thread && self.thread_through {
            Some(if self.tightening {
                SkillState::Tighten
            } else {
                SkillState::PullThrough
            })
        } else if self.needle_held && self.needle_in_tissue && self.needle_regrasped {
            Some(SkillState::Regrasp)
        } else if self.needle_held && self.needle_in_tissue {
            Some(SkillState::PushThrough)
        } else if self.needle_held && self.needle_pressing {
            Some(SkillState::Puncture)
        } else if self.thread_held {
            Some(SkillState::Grasping)
        } else if self.needle_released {
            Some(SkillState::Release)
        } else {
            None
        }
    }
}

impl Default for SkillMachine {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use SkillState::*;

    /// Feed `script` (tick, event kinds, force) tick by tick; the transitions, as (tick, from, to).
    fn run(
        machine: &mut SkillMachine,
        script: &[(u64, &[EventKind], f32)],
    ) -> Vec<(u64, SkillState, SkillState)> {
        run_ticks(machine, script, |force_n| (force_n, 0.0))
    }

    /// Feed `script` (tick, event kinds, a value) tick by tick, each tick's force and thread pull made from
    /// its value by `pulls`; the transitions, as (tick, from, to).
    fn run_ticks(
        machine: &mut SkillMachine,
        script: &[(u64, &[EventKind], f32)],
        pulls: impl Fn(f32) -> (f32, f32),
    ) -> Vec<(u64, SkillState, SkillState)> {
        let mut out = Vec::new();
        for &(tick, kinds, value) in script {
            for &kind in kinds {
                let event = SessionEvent {
                    tick,
                    tool: 0,
                    kind,
                };
                machine.on_event(&event, |t| out.push((t.tick, t.from, t.to)));
            }
            let (force_n, thread_pull_n) = pulls(value);
            machine.on_tick(tick, force_n, thread_pull_n, |t| {
                out.push((t.tick, t.from, t.to))
            });
        }
        out
    }

    /// Like [`run`], with the thread's pull on the tool instead of the force (the tighten threshold's input).
    fn run_pulled(
        machine: &mut SkillMachine,
        script: &[(u64, &[EventKind], f32)],
    ) -> Vec<(u64, SkillState, SkillState)> {
        run_ticks(machine, script, |pull_n| (0.0, pull_n))
    }

    #[test]
    fn a_probe_joins_approaches_touches_and_leaves() {
        use EventKind as E;
        let mut m = SkillMachine::new();
        let out = run(
            &mut m,
            &[
                (0, &[E::Joined], 0.0),
                (10, &[E::ApproachBegin], 0.0),
                (20, &[E::ContactBegin], 1.0),
                (30, &[E::ContactEnd], 0.0),
                (40, &[E::ApproachEnd], 0.0),
                (50, &[E::Left], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (10, Idle, Approach),
                (20, Approach, Contact),
                (30, Contact, Approach),
                (40, Approach, Idle)
            ]
        );
        assert_eq!(m.transitions(), 4);
    }

    #[test]
    fn a_hand_off_is_release_on_the_driver_and_regrasp_then_pull_through_on_the_grasper() {
        use EventKind as E;
        // The driver: pushing through, it opens its jaws and leaves the needle; the grasper takes it.
        let mut driver = SkillMachine::new();
        let out = run(
            &mut driver,
            &[
                (0, &[E::Joined, E::NeedleGraspBegin], 0.0),
                (10, &[E::ContactBegin, E::PushThroughBegin], 0.0),
                (
                    20,
                    &[E::NeedleReleaseBegin, E::PushThroughEnd, E::NeedleGraspEnd],
                    0.0,
                ),
                (30, &[E::ContactEnd], 0.0),
                (40, &[E::NeedleReleaseEnd], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (0, Idle, NeedleGrasped),
                (10, NeedleGrasped, Contact),
                (10, Contact, PushThrough),
                (20, PushThrough, Release),
                (40, Release, Idle)
            ]
        );
        // The grasper: takes the needle in the tissue, draws it out until its tail leaves, then the thread.
        let mut grasper = SkillMachine::new();
        let out = run_pulled(
            &mut grasper,
            &[
                (0, &[E::Joined], 0.0),
                (
                    40,
                    &[
                        E::NeedleGraspBegin,
                        E::NeedleRegraspBegin,
                        E::PushThroughBegin,
                    ],
                    0.0,
                ),
                (50, &[E::ThreadThroughBegin], 0.2),
                // (Ends come innermost first, as the detector sends them.)
                (60, &[E::PushThroughEnd, E::NeedleRegraspEnd], 0.3),
                (70, &[], 1.5),
            ],
        );
        assert_eq!(
            out,
            [
                (40, Idle, NeedleGrasped),
                (40, NeedleGrasped, Regrasp),
                (60, Regrasp, PullThrough),
                (70, PullThrough, Tighten)
            ]
        );
    }

    #[test]
    fn a_needle_driver_grasps_punctures_pushes_through_pulls_through_and_tightens() {
        use EventKind as E;
        let mut m = SkillMachine::new();
        let out = run_pulled(
            &mut m,
            &[
                (0, &[E::Joined, E::NeedleGraspBegin], 0.0),
                (10, &[E::ApproachBegin], 0.0),
                (20, &[E::ContactBegin, E::NeedlePressBegin], 0.0),
                (
                    30,
                    &[E::PushThroughBegin, E::Puncture, E::NeedlePressEnd],
                    0.0,
                ),
                // Pressing its exit from inside is still pushing through.
                (40, &[E::NeedlePressBegin], 0.0),
                (45, &[E::NeedlePressEnd, E::Puncture], 0.0),
                (50, &[E::ThreadThroughBegin], 0.2),
                (60, &[E::PushThroughEnd, E::ContactEnd], 0.3),
                (70, &[], 1.5), // drawn tight
                (80, &[], 0.5), // eased off
                (90, &[E::ThreadThroughEnd], 0.0),
                (95, &[E::ApproachEnd], 0.0),
                (100, &[E::NeedleGraspEnd, E::Left], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (0, Idle, NeedleGrasped),
                (20, NeedleGrasped, Contact),
                (20, Contact, Puncture),
                (30, Puncture, PushThrough),
                (60, PushThrough, PullThrough),
                (70, PullThrough, Tighten),
                (80, Tighten, PullThrough),
                (90, PullThrough, NeedleGrasped),
                (100, NeedleGrasped, Idle)
            ]
        );
        // (The script calls one tick per line: one ended tight.)
        assert_eq!(m.ticks_in()[Tighten.index()], 1);
    }

    #[test]
    fn a_grasper_on_a_thread_grasps_it_then_pulls_it_through_and_tightens() {
        use EventKind as E;
        let mut m = SkillMachine::new();
        let out = run_pulled(
            &mut m,
            &[
                (0, &[E::Joined], 0.0),
                // A thread with no holes yet, in the jaws: grasping.
                (10, &[E::ThreadGraspBegin], 0.1),
                (20, &[E::ThreadThroughBegin], 0.5),
                (30, &[], 2.0),
                (40, &[E::ThreadGraspEnd], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (10, Idle, Grasping),
                (20, Grasping, PullThrough),
                (30, PullThrough, Tighten),
                (40, Tighten, Idle)
            ]
        );
    }

    #[test]
    fn grasp_pull_release_goes_through_every_grasping_state() {
        use EventKind as E;
        let mut m = SkillMachine::with(100, 0.5);
        let out = run(
            &mut m,
            &[
                (0, &[E::Joined, E::ApproachBegin, E::ContactBegin], 0.2),
                (5, &[E::GraspBegin], 0.2),
                (6, &[], 0.8), // pulling
                (7, &[], 0.3), // eased off
                (8, &[E::GraspEnd], 0.3),
                (9, &[], 0.1), // still on the tissue: releasing
                (12, &[E::ContactEnd], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (0, Idle, Approach),
                (0, Approach, Contact),
                (5, Contact, Grasping),
                (6, Grasping, Pulling),
                (7, Pulling, Grasping),
                (8, Grasping, Releasing),
                (12, Releasing, Approach)
            ]
        );
    }

    #[test]
    fn releasing_times_out_into_contact_and_leaving_resets_everything() {
        use EventKind as E;
        let mut m = SkillMachine::with(3, 0.5);
        let out = run(
            &mut m,
            &[
                (0, &[E::Joined, E::ContactBegin, E::GraspBegin], 0.0),
                (1, &[E::GraspEnd], 0.0),
                (2, &[], 0.0),
                (3, &[], 0.0),
                (4, &[], 0.0), // 1 + 3: the release is over, the probe still touches
                (5, &[E::BurnBegin], 0.0),
                (6, &[E::CutBegin], 0.0), // burning outranks cutting
                (7, &[E::BurnEnd], 0.0),
                (8, &[E::Left], 0.0),
            ],
        );
        assert_eq!(
            out,
            [
                (0, Idle, Contact), // each event settles: the tick's two events are two transitions
                (0, Contact, Grasping),
                (1, Grasping, Releasing),
                (4, Releasing, Contact),
                (5, Contact, Cauterizing),
                (7, Cauterizing, Cutting),
                (8, Cutting, Idle)
            ]
        );
        // Time per state: ticks 0 grasping; 1-3 releasing; 4 contact; 5-6 cauterizing; 7 cutting; 8 idle.
        let t = m.ticks_in();
        assert_eq!(
            (
                t[Grasping.index()],
                t[Releasing.index()],
                t[Contact.index()]
            ),
            (1, 3, 1)
        );
        assert_eq!(
            (t[Cauterizing.index()], t[Cutting.index()], t[Idle.index()]),
            (2, 1, 1)
        );
        assert_eq!(t.iter().sum::<u64>(), 9);
    }
}

//! Surgical skill states: a finite-state machine per participant, driven by [`SessionEvent`]s, that records
//! its transitions and the time spent in each state (the suturing prototype's scoring model, in general form).
//!
//! Owns: [`SkillState`], [`Transition`], [`SkillMachine`].
//!
//! The machine keeps the conditions the events set (driving, near tissue, touching, grasping, cutting,
//! burning) and derives its state from them by priority: not driven is idle; burning is cauterizing; cutting
//! is cutting; grasping is pulling while the force on the jaws exceeds the pull threshold, else grasping; after
//! jaws open on tissue the machine is releasing until the tool leaves the tissue or the release time passes;
//! touching is contact; near is approach; else idle. Suturing extends it: new states (needle grasped,
//! puncture, push-through, pull-through) are new variants of [`SkillState`], new conditions set by new event
//! kinds, and new arms of [`SkillMachine::derive`] above the ones they refine.
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
}

impl SkillState {
    /// Every state, in declaration order.
    pub const ALL: [SkillState; 8] = [
        SkillState::Idle,
        SkillState::Approach,
        SkillState::Contact,
        SkillState::Grasping,
        SkillState::Pulling,
        SkillState::Cutting,
        SkillState::Cauterizing,
        SkillState::Releasing,
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
            EventKind::HarmBegin | EventKind::HarmEnd | EventKind::TissueFault => {}
        }
        self.settle(event.tick, sink);
    }

    /// The end of tick `tick`: the force on the tool then (for pulling), counted in the state it ends in.
    /// Call after the tick's events.
    pub fn on_tick(&mut self, tick: u64, force_n: f32, sink: impl FnMut(Transition)) {
        self.pulling = self.grasping && force_n > self.pull_threshold_n;
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
        } else if self.grasping && self.pulling {
            SkillState::Pulling
        } else if self.grasping {
            SkillState::Grasping
        } else if self.contact && tick < self.release_until_tick {
            SkillState::Releasing
        } else if self.contact {
            SkillState::Contact
        } else if self.near {
            SkillState::Approach
        } else {
            SkillState::Idle
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
        let mut out = Vec::new();
        for &(tick, kinds, force_n) in script {
            for &kind in kinds {
                let event = SessionEvent {
                    tick,
                    tool: 0,
                    kind,
                };
                machine.on_event(&event, |t| out.push((t.tick, t.from, t.to)));
            }
            machine.on_tick(tick, force_n, |t| out.push((t.tick, t.from, t.to)));
        }
        out
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

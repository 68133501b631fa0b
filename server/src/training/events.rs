//! Session events: what happened to a tool, as edges of its per-tick activity (contact began, a grasp ended,
//! the force rose above the harm threshold), stamped with the tick.
//!
//! Owns: [`ToolActivity`] (one tool's state on one tick, as the training layer sees it), [`EventKind`],
//! [`SessionEvent`] and [`EventDetector`] (turns a tool's activity, tick after tick, into events).
//!
//! The instruments (grasp, cut, cauterize) set `grasping`, `cutting` and `burning` from their jaw and edge
//! states; the probe sets none of them. Suturing sets its own flags from the tool output's
//! [`crate::sim::SutureActivity`]: the needle held, its tip pressing a surface, the needle through tissue, the
//! thread held and running through holes, and each puncture (an event of its own, not an edge).
//!
//! Touches chatter: a probe lifting off a dent that follows it up leaves and retouches for a few ticks. So
//! contact and approach end only after [`EventDetector::END_DEBOUNCE_TICKS`] ticks without them (a touch
//! broken for less is one touch), and harm ends only below 95% of its threshold. A device leaving ends
//! everything at once.
//!
//! Must not: allocate (the detector can run on the sim thread) or read a clock (tick numbers only).

use serde::{Deserialize, Serialize};

use crate::sim::ToolOutput;

/// One tool's state on one tick, as the training layer sees it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ToolActivity {
    /// A device drives the tool (present, fresh pose).
    pub active: bool,
    /// A tissue surface lies within the look-ahead of the tool (it is approaching or leaving), or it touches.
    pub near: bool,
    /// The tool touches tissue.
    pub in_contact: bool,
    /// Jaws closed on tissue.
    pub grasping: bool,
    /// A sharp edge is cutting.
    pub cutting: bool,
    /// An active tip is burning tissue.
    pub burning: bool,
    /// Magnitude of the tissue's force on the tool, N.
    pub force_n: f32,
    /// Where the device puts the tool, world, mm: the hand's instrument tip (the simulated tool lags it only
    /// where tissue holds it back, and when it is dragged to a joining hand).
    pub tip_world_mm: [f32; 3],
    /// The simulated tool's origin, world, mm (where it touches: held back by the tissue it presses).
    pub tool_world_mm: [f32; 3],
    /// The tool's jaws hold a suture needle.
    pub needle_held: bool,
    /// The jaws took the needle they hold while it ran through tissue (a regrasp), and it still does.
    pub needle_regrasped: bool,
    /// The tool let its needle go in the tissue, and no jaws hold it since.
    pub needle_released: bool,
    /// The needle's tip presses a surface (before it punctures).
    pub needle_pressing: bool,
    /// The needle runs through tissue.
    pub needle_in_tissue: bool,
    /// Surfaces the needle has punctured so far.
    pub punctures: u32,
    /// Where the needle's newest hole lies on its tissue at rest, world, mm (where a puncture this tick went
    /// in, on the undeformed tissue, as marks are drawn).
    pub newest_hole_rest_mm: Option<[f32; 3]>,
    /// The tool's jaws hold a suture thread.
    pub thread_held: bool,
    /// The thread the tool draws (its needle's, or the one in its jaws) runs through holes.
    pub thread_through: bool,
    /// The thread's pull on the tool, N.
    pub thread_pull_n: f32,
    /// The thread the tool draws ties a knot of throws (a half knot, a square knot, ...), as last read.
    pub knot_tied: bool,
    /// Those throws (None: no knot).
    pub knot: Option<crate::interaction::suture::Throws>,
}

impl ToolActivity {
    /// What a tick's [`ToolOutput`] says of a tool driven (`active`) or not: a grasper grasps while its jaws
    /// hold tissue, a scalpel cuts while its edge cuts tissue, a cautery tool burns while its current burns
    /// tissue.
    pub fn from_output(active: bool, out: &ToolOutput) -> Self {
        let force_n = out.force_world_n.norm();
        Self {
            active,
            near: active && (out.in_contact || out.plane_count > 0),
            in_contact: active && out.in_contact,
            // A needle driver's attachments are its needle's tip and holes, not tissue in its jaws.
            // (A driver that let its needle go still counts the tip's pressed point while the needle lies.)
            grasping: active
                && out.attachments > 0
                && !out.suture.needle_held
                && !out.suture.needle_released,
            cutting: active && out.cutting,
            burning: active && out.burning,
            force_n: if force_n.is_finite() { force_n } else { 0.0 },
            tip_world_mm: out.device_world_mm.into(),
            tool_world_mm: out.position_world_mm.into(),
            needle_held: active && out.suture.needle_held,
            needle_regrasped: active && out.suture.needle_regrasped,
            needle_released: active && out.suture.needle_released,
            needle_pressing: active && out.suture.needle_pressing,
            needle_in_tissue: active && out.suture.needle_in_tissue,
            punctures: out.suture.punctures,
            newest_hole_rest_mm: out
                .suture
                .newest_hole_rest_mm
                .filter(|p| active && p.iter().all(|c| c.is_finite()))
                .map(Into::into),
            thread_held: active && out.suture.thread_held,
            thread_through: active && out.suture.thread_holes > 0,
            thread_pull_n: if active && out.suture.thread_pull_n.is_finite() {
                out.suture.thread_pull_n
            } else {
                0.0
            },
            knot_tied: active
                && matches!(
                    out.suture.knot,
                    crate::interaction::suture::KnotKind::Throws(_)
                ),
            knot: match out.suture.knot {
                crate::interaction::suture::KnotKind::Throws(throws) if active => Some(throws),
                _ => None,
            },
        }
    }
}

/// What happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum EventKind {
    /// A device began driving the tool.
    Joined,
    /// The device stopped driving it (left, timed out, refused).
    Left,
    /// A surface came within the tool's look-ahead.
    ApproachBegin,
    /// No surface within the look-ahead any more.
    ApproachEnd,
    /// The tool touched tissue.
    ContactBegin,
    /// It no longer touches.
    ContactEnd,
    /// Jaws closed on tissue.
    GraspBegin,
    /// Jaws let go.
    GraspEnd,
    /// A sharp edge began cutting.
    CutBegin,
    /// It stopped.
    CutEnd,
    /// An active tip began burning.
    BurnBegin,
    /// It stopped.
    BurnEnd,
    /// The tool's jaws took a suture needle (or joined holding one).
    NeedleGraspBegin,
    /// They no longer hold it.
    NeedleGraspEnd,
    /// The tool let its needle go with the needle in tissue (the hand-off begins).
    NeedleReleaseBegin,
    /// Jaws hold that needle again (or it left the tissue, or the tool left).
    NeedleReleaseEnd,
    /// The tool's jaws took a needle running through tissue (on the far side of a bite).
    NeedleRegraspBegin,
    /// It no longer runs through tissue, or they let it go.
    NeedleRegraspEnd,
    /// The needle's tip began pressing a surface.
    NeedlePressBegin,
    /// It no longer presses one (it punctured, slid off or lifted).
    NeedlePressEnd,
    /// The needle's tip punctured a surface (one event per puncture).
    Puncture,
    /// The needle began running through tissue.
    PushThroughBegin,
    /// It no longer does (its tail left the last hole, or it was drawn back out).
    PushThroughEnd,
    /// The thread the tool draws began running through holes.
    ThreadThroughBegin,
    /// It no longer does.
    ThreadThroughEnd,
    /// The tool's jaws took a suture thread.
    ThreadGraspBegin,
    /// They let it go (or it slipped out).
    ThreadGraspEnd,
    /// The force on the tool rose above the harm threshold.
    HarmBegin,
    /// It fell below it again.
    HarmEnd,
    /// The anti-divergence guard reset an object this tick (scene-wide; reported on every tool).
    TissueFault,
    /// The thread the tool draws came to tie a knot of throws (declared last: recordings keep the older
    /// kinds' numbers).
    KnotTied,
    /// It ties none any more (undone, or the tool let go of it).
    KnotUndone,
}

impl EventKind {
    /// Every kind, in declaration order (reports list counts in this order).
    pub const ALL: [EventKind; 32] = [
        EventKind::Joined,
        EventKind::Left,
        EventKind::ApproachBegin,
        EventKind::ApproachEnd,
        EventKind::ContactBegin,
        EventKind::ContactEnd,
        EventKind::GraspBegin,
        EventKind::GraspEnd,
        EventKind::CutBegin,
        EventKind::CutEnd,
        EventKind::BurnBegin,
        EventKind::BurnEnd,
        EventKind::NeedleGraspBegin,
        EventKind::NeedleGraspEnd,
        EventKind::NeedleReleaseBegin,
        EventKind::NeedleReleaseEnd,
        EventKind::NeedleRegraspBegin,
        EventKind::NeedleRegraspEnd,
        EventKind::NeedlePressBegin,
        EventKind::NeedlePressEnd,
        EventKind::Puncture,
        EventKind::PushThroughBegin,
        EventKind::PushThroughEnd,
        EventKind::ThreadThroughBegin,
        EventKind::ThreadThroughEnd,
        EventKind::ThreadGraspBegin,
        EventKind::ThreadGraspEnd,
        EventKind::HarmBegin,
        EventKind::HarmEnd,
        EventKind::TissueFault,
        EventKind::KnotTied,
        EventKind::KnotUndone,
    ];

    /// Its index in [`EventKind::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Its name in reports (snake case).
    pub fn name(self) -> &'static str {
        match self {
            EventKind::Joined => "joined",
            EventKind::Left => "left",
            EventKind::ApproachBegin => "approach_begin",
            EventKind::ApproachEnd => "approach_end",
            EventKind::ContactBegin => "contact_begin",
            EventKind::ContactEnd => "contact_end",
            EventKind::GraspBegin => "grasp_begin",
            EventKind::GraspEnd => "grasp_end",
            EventKind::CutBegin => "cut_begin",
            EventKind::CutEnd => "cut_end",
            EventKind::BurnBegin => "burn_begin",
            EventKind::BurnEnd => "burn_end",
            EventKind::NeedleGraspBegin => "needle_grasp_begin",
            EventKind::NeedleGraspEnd => "needle_grasp_end",
            EventKind::NeedleReleaseBegin => "needle_release_begin",
            EventKind::NeedleReleaseEnd => "needle_release_end",
            EventKind::NeedleRegraspBegin => "needle_regrasp_begin",
            EventKind::NeedleRegraspEnd => "needle_regrasp_end",
            EventKind::NeedlePressBegin => "needle_press_begin",
            EventKind::NeedlePressEnd => "needle_press_end",
            EventKind::Puncture => "puncture",
            EventKind::PushThroughBegin => "push_through_begin",
            EventKind::PushThroughEnd => "push_through_end",
            EventKind::ThreadGraspBegin => "thread_grasp_begin",
            EventKind::ThreadGraspEnd => "thread_grasp_end",
            EventKind::ThreadThroughBegin => "thread_through_begin",
            EventKind::ThreadThroughEnd => "thread_through_end",
            EventKind::HarmBegin => "harm_begin",
            EventKind::HarmEnd => "harm_end",
            EventKind::TissueFault => "tissue_fault",
            EventKind::KnotTied => "knot_tied",
            EventKind::KnotUndone => "knot_undone",
        }
    }
}

/// An event on one tool at one tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SessionEvent {
    /// Tick index.
    pub tick: u64,
    /// Tool index, in world order.
    pub tool: u8,
    /// What happened.
    pub kind: EventKind,
}

/// Turns one tool's activity, tick after tick, into events (edges of its flags).
#[derive(Debug, Clone, Copy)]
pub struct EventDetector {
    tool: u8,
    harm_threshold_n: f32,
    /// The last tick's activity, debounced.
    last: ToolActivity,
    harmful: bool,
    ticks_without_contact: u32,
    ticks_without_near: u32,
}

impl EventDetector {
    /// Contact and approach end after this many ticks without them.
    pub const END_DEBOUNCE_TICKS: u32 = 10;
    /// Harm ends below this fraction of its threshold.
    pub const HARM_END_FRACTION: f32 = 0.95;

    /// A detector for tool `tool`, whose harm events fire above `harm_threshold_n`.
    pub fn new(tool: u8, harm_threshold_n: f32) -> Self {
        Self {
            tool,
            harm_threshold_n,
            last: ToolActivity::default(),
            harmful: false,
            ticks_without_contact: 0,
            ticks_without_near: 0,
        }
    }

    /// The last tick's activity as the events saw it (contact and approach debounced).
    pub fn debounced(&self) -> &ToolActivity {
        &self.last
    }

    /// The events of tick `tick`, given the tool's activity then and whether an object was reset, in a fixed
    /// order: beginnings outermost first (joined, approach, contact, grasp, cut, burn, harm), then endings
    /// innermost first, then the fault.
    pub fn detect(
        &mut self,
        tick: u64,
        now: &ToolActivity,
        tissue_fault: bool,
        mut emit: impl FnMut(SessionEvent),
    ) {
        let mut send = |kind| {
            emit(SessionEvent {
                tick,
                tool: self.tool,
                kind,
            })
        };
        let last = self.last;
        let mut now = *now;
        if now.active {
            let quiet = |flag: bool, count: &mut u32| {
                *count = if flag { 0 } else { count.saturating_add(1) };
                *count
            };
            let no_contact = quiet(now.in_contact, &mut self.ticks_without_contact);
            now.in_contact |= last.in_contact && no_contact < Self::END_DEBOUNCE_TICKS;
            let no_near = quiet(now.near || now.in_contact, &mut self.ticks_without_near);
            now.near |= last.near && no_near < Self::END_DEBOUNCE_TICKS;
            now.near |= now.in_contact;
        }
        let harmful = now.active
            && if self.harmful {
                now.force_n >= Self::HARM_END_FRACTION * self.harm_threshold_n
            } else {
                now.force_n > self.harm_threshold_n
            };
        let edges = [
            (last.active, now.active, EventKind::Joined, EventKind::Left),
            (
                last.near,
                now.near,
                EventKind::ApproachBegin,
                EventKind::ApproachEnd,
            ),
            (
                last.in_contact,
                now.in_contact,
                EventKind::ContactBegin,
                EventKind::ContactEnd,
            ),
            (
                last.grasping,
                now.grasping,
                EventKind::GraspBegin,
                EventKind::GraspEnd,
            ),
            (
                last.cutting,
                now.cutting,
                EventKind::CutBegin,
                EventKind::CutEnd,
            ),
            (
                last.burning,
                now.burning,
                EventKind::BurnBegin,
                EventKind::BurnEnd,
            ),
            (
                last.needle_held,
                now.needle_held,
                EventKind::NeedleGraspBegin,
                EventKind::NeedleGraspEnd,
            ),
            (
                last.needle_released,
                now.needle_released,
                EventKind::NeedleReleaseBegin,
                EventKind::NeedleReleaseEnd,
            ),
            (
                last.needle_regrasped,
                now.needle_regrasped,
                EventKind::NeedleRegraspBegin,
                EventKind::NeedleRegraspEnd,
            ),
            (
                last.needle_pressing,
                now.needle_pressing,
                EventKind::NeedlePressBegin,
                EventKind::NeedlePressEnd,
            ),
            (
                last.needle_in_tissue,
                now.needle_in_tissue,
                EventKind::PushThroughBegin,
                EventKind::PushThroughEnd,
            ),
            // The thread running through holes is outer to a hand holding it: a grasp on a thread already
            // through is pulling through from its first tick.
            (
                last.thread_through,
                now.thread_through,
                EventKind::ThreadThroughBegin,
                EventKind::ThreadThroughEnd,
            ),
            (
                last.thread_held,
                now.thread_held,
                EventKind::ThreadGraspBegin,
                EventKind::ThreadGraspEnd,
            ),
            (
                last.knot_tied,
                now.knot_tied,
                EventKind::KnotTied,
                EventKind::KnotUndone,
            ),
            (
                self.harmful,
                harmful,
                EventKind::HarmBegin,
                EventKind::HarmEnd,
            ),
        ];
        for (was, is, begin, _) in edges {
            if is && !was {
                send(begin);
            }
        }
        // Each puncture since the last tick (a needle punctures at most a few surfaces a tick); a count that
        // went down (a new needle, a reset) punctured nothing, nor one the jaws took with the needle (a regrasp
        // takes its punctures so far).
        if now.active && last.active && now.needle_held && last.needle_held {
            for _ in 0..now.punctures.saturating_sub(last.punctures).min(8) {
                send(EventKind::Puncture);
            }
        }
        for (was, is, _, end) in edges.iter().rev() {
            if *was && !*is {
                send(*end);
            }
        }
        if tissue_fault {
            send(EventKind::TissueFault);
        }
        self.last = now;
        self.harmful = harmful;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn kinds(detector: &mut EventDetector, tick: u64, a: ToolActivity) -> Vec<EventKind> {
        let mut out = Vec::new();
        detector.detect(tick, &a, false, |e| {
            assert_eq!(e.tick, tick);
            out.push(e.kind)
        });
        out
    }

    #[test]
    fn edges_become_events_in_nesting_order() {
        let mut d = EventDetector::new(1, 2.0);
        let idle = ToolActivity {
            active: true,
            ..ToolActivity::default()
        };
        let touching = ToolActivity {
            near: true,
            in_contact: true,
            force_n: 2.5,
            ..idle
        };
        assert_eq!(kinds(&mut d, 0, idle), [EventKind::Joined]);
        assert_eq!(kinds(&mut d, 1, idle), []);
        assert_eq!(
            kinds(&mut d, 2, touching),
            [
                EventKind::ApproachBegin,
                EventKind::ContactBegin,
                EventKind::HarmBegin
            ]
        );
        assert_eq!(kinds(&mut d, 3, touching), []);
        // Lifting off for fewer than the debounce ticks, then touching again, is one touch; the force below
        // the threshold but above 95% of it is still harm.
        let lifted = ToolActivity {
            in_contact: false,
            force_n: 1.95,
            ..touching
        };
        for tick in 4..4 + u64::from(EventDetector::END_DEBOUNCE_TICKS) - 1 {
            assert_eq!(kinds(&mut d, tick, lifted), []);
        }
        assert_eq!(kinds(&mut d, 20, touching), []);
        let lifted = ToolActivity {
            force_n: 0.0,
            ..lifted
        };
        assert_eq!(kinds(&mut d, 21, lifted), [EventKind::HarmEnd]);
        for tick in 22..30 {
            assert_eq!(kinds(&mut d, tick, lifted), [], "tick {tick}");
        }
        assert_eq!(kinds(&mut d, 30, lifted), [EventKind::ContactEnd]);
        assert_eq!(
            kinds(&mut d, 31, touching),
            [EventKind::ContactBegin, EventKind::HarmBegin]
        );
        assert_eq!(
            kinds(&mut d, 32, ToolActivity::default()),
            [
                EventKind::HarmEnd,
                EventKind::ContactEnd,
                EventKind::ApproachEnd,
                EventKind::Left
            ]
        );
    }

    #[test]
    fn a_needle_and_a_thread_become_suturing_events_and_every_puncture_one() {
        let mut d = EventDetector::new(0, 10.0);
        let held = ToolActivity {
            active: true,
            needle_held: true,
            ..ToolActivity::default()
        };
        assert_eq!(
            kinds(&mut d, 0, held),
            [EventKind::Joined, EventKind::NeedleGraspBegin]
        );
        let pressing = ToolActivity {
            needle_pressing: true,
            ..held
        };
        assert_eq!(kinds(&mut d, 1, pressing), [EventKind::NeedlePressBegin]);
        // The pop: through the surface, one puncture.
        let through = ToolActivity {
            needle_in_tissue: true,
            punctures: 1,
            ..held
        };
        assert_eq!(
            kinds(&mut d, 2, through),
            [
                EventKind::PushThroughBegin,
                EventKind::Puncture,
                EventKind::NeedlePressEnd
            ]
        );
        // Out of one edge and into the other in one tick: two punctures.
        let across = ToolActivity {
            punctures: 3,
            thread_through: true,
            ..through
        };
        assert_eq!(
            kinds(&mut d, 3, across),
            [
                EventKind::ThreadThroughBegin,
                EventKind::Puncture,
                EventKind::Puncture
            ]
        );
        // A new needle's count starts again: no puncture.
        let fresh = ToolActivity {
            punctures: 0,
            ..across
        };
        assert_eq!(kinds(&mut d, 4, fresh), []);
        // A grasper taking a thread already through its holes.
        let mut g = EventDetector::new(1, 10.0);
        let idle = ToolActivity {
            active: true,
            ..ToolActivity::default()
        };
        assert_eq!(kinds(&mut g, 0, idle), [EventKind::Joined]);
        let drawing = ToolActivity {
            thread_held: true,
            thread_through: true,
            thread_pull_n: 1.0,
            ..idle
        };
        assert_eq!(
            kinds(&mut g, 1, drawing),
            [EventKind::ThreadThroughBegin, EventKind::ThreadGraspBegin]
        );
        // The thread it draws comes to tie a knot, then comes undone.
        let tied = ToolActivity {
            knot_tied: true,
            ..drawing
        };
        assert_eq!(kinds(&mut g, 2, tied), [EventKind::KnotTied]);
        assert_eq!(kinds(&mut g, 3, tied), []);
        assert_eq!(kinds(&mut g, 4, drawing), [EventKind::KnotUndone]);
    }

    #[test]
    fn every_kind_has_its_index_and_a_distinct_name() {
        for (i, kind) in EventKind::ALL.iter().enumerate() {
            assert_eq!(kind.index(), i);
        }
        let mut names: Vec<_> = EventKind::ALL.iter().map(|k| k.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), EventKind::ALL.len());
    }
}

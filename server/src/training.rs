//! The training layer: what a session measures of each surgeon (issue "Training sessions").
//!
//! Everything here is fed from the server tick's outputs ([`observer::TickView`]), tick by tick, so it runs
//! the same behind a replay of a recording (`sinew report`) as it would live, and its answers follow from the
//! recorded inputs bit for bit.
//!
//! - [`events`]: contact, grasp, cut, burn, harm and fault events, as edges of a tool's activity;
//! - [`skill_state`]: the surgical state machine the events drive, with time per state;
//! - [`metrics`]: task time, path length and economy, contact time, forces, harm;
//! - [`exercise`]: an exercise's targets, clock and errors, scored from the events;
//! - [`knot_score`]: the knot a suture exercise read, and which knots tie a stitch off;
//! - [`observer`]: events, states and metrics per tool (and the exercise), fed one tick at a time;
//! - [`pattern_cutting`]: a pattern cut out of a sheet, scored as MISTELS scores FLS's task;
//! - [`wound_gap`]: how far a wound between two objects is open (a stitch's result).

pub mod events;
pub mod exercise;
pub mod knot_score;
pub mod metrics;
pub mod observer;
pub mod pattern_cutting;
pub mod skill_state;
pub mod wound_gap;

pub use events::{EventDetector, EventKind, SessionEvent, ToolActivity};
pub use exercise::{
    ExerciseErrors, ExerciseRun, ExerciseScore, LiveScore, RankedPair, RankingResult, TargetHit,
};
pub use knot_score::{KnotScore, secure_knot};
pub use metrics::{MetricsConfig, MetricsSummary, ParticipantMetrics};
pub use observer::{LiveTraining, SessionObserver, TickView};
pub use pattern_cutting::{PatternCutScore, PatternJudge};
pub use skill_state::{SkillMachine, SkillState, Transition};
pub use wound_gap::{wound_gap_between_mm, wound_gap_mm};

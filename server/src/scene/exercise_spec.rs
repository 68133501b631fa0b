//! A training exercise as a world file states it (`[exercise]`): what to touch, with which tool, in what order,
//! within what time and how gently. Plain data, validated by the loader; the training layer runs and scores it
//! (`crate::training::exercise`).
//!
//! ```toml
//! [exercise]
//! name = "coordination"
//! kind = "coordination"        # or "accurate-touch"
//! time_limit_s = 60.0
//! depth_limit_mm = 3.0         # accurate-touch: deepest press allowed at a target, mm
//! [[exercise.targets]]
//! at_mm = [-20.0, 10.0, 0.0]   # a point on the tissue surface, world frame
//! radius_mm = 5.0              # a touch this close (across the surface) hits it
//! tool = "left-probe"          # coordination: the tool whose colour the target shows
//! ```
//!
//! A `kind = "pattern-cutting"` exercise has no targets but a pattern: two concentric circles marked on a sheet
//! fixed by clips, and the piece inside is to be cut out along the band between them.
//!
//! ```toml
//! [exercise.pattern]
//! object = "gauze"             # a sheet with fixed vertices (the clips)
//! centre_mm = [0.0, 0.0, 0.0]  # on the sheet at rest, world frame
//! inner_radius_mm = 19.5
//! outer_radius_mm = 20.5
//! ```
//!
//! A `kind = "stiffness-ranking"` exercise names objects instead of targets: `samples = ["a", "b", "c"]`.
//!
//! A `kind = "suture"` exercise has exactly two targets, the marks a stitch goes in at and comes out at (as
//! FLS's suturing task marks them on either side of the slit): `[[exercise.targets]]` the entry mark, then the
//! exit mark, each a point on a tissue's rest surface with the radius a puncture must land within. It may name
//! the wound's two edges, `wound = ["left", "right"]` (two objects facing each other): its gap after the
//! stitch is then scored too (closed to [`SUTURE_GAP_LIMIT_MM`] or less to pass).

use serde::{Deserialize, Serialize};

/// The widest a suture exercise's wound may be left open at its end and pass, mm (issue 32's closure: a 5 mm
/// gap closed to 1 mm or less).
pub const SUTURE_GAP_LIMIT_MM: f32 = 1.0;

/// What the exercise trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ExerciseKind {
    /// Touch targets one after another, each with the tool it names (laparoscopic basic skills: coordination).
    /// Scored by time, path and errors (wrong tool, a touch off the target).
    Coordination,
    /// Touch marked points on deformable tissue without pressing deeper than a limit. Scored by accuracy
    /// (distance from the mark) and harm (presses too deep).
    AccurateTouch,
    /// Press tissue samples of unknown stiffness and rank them: explore freely, then touch each sample once
    /// more, softest first; the order of the last touches is the answer. Scored by the pairs ranked right,
    /// against each pair's stiffness ratio (force sensitivity).
    StiffnessRanking,
    /// Put one stitch through marked points: the needle goes in at the entry mark and comes out at the exit
    /// mark (the punctures through the wound's faces between them are not judged). Scored by the marks hit
    /// and how far from them the needle went in and out, mm (FLS's intracorporeal suture task: time and mm
    /// off the marks; the wound's gap and the knot come with the knot).
    Suture,
    /// Cut a marked circle out of a clipped sheet, between its two marked circles (FLS's pattern-cutting task,
    /// scored as MISTELS scores it: the cutoff time less the time taken less the percentage area cut outside
    /// the band).
    PatternCutting,
}

impl ExerciseKind {
    /// The name the world file uses.
    pub fn as_str(self) -> &'static str {
        match self {
            ExerciseKind::Coordination => "coordination",
            ExerciseKind::AccurateTouch => "accurate-touch",
            ExerciseKind::StiffnessRanking => "stiffness-ranking",
            ExerciseKind::Suture => "suture",
            ExerciseKind::PatternCutting => "pattern-cutting",
        }
    }
}

/// One target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetSpec {
    /// A point on the tissue's rest surface, world frame, mm.
    pub at_mm: [f32; 3],
    /// A touch whose point lies this close to `at_mm` across the surface hits the target, mm.
    pub radius_mm: f32,
    /// The tool that must touch it (by index in the world's tools); None: any tool.
    pub tool: Option<usize>,
}

/// A tissue sample to rank (an object of the world).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleSpec {
    /// The object's index in the world.
    pub object: usize,
    /// Its name.
    pub name: String,
    /// Its per-edge stiffness, N/mm (the truth the ranking is scored against).
    pub stiffness_n_per_mm: f32,
    /// Its rest extent across the surface, world x-y, mm: a touch there touches this sample.
    pub min_xy_mm: [f32; 2],
    /// Upper corner.
    pub max_xy_mm: [f32; 2],
}

/// A pattern-cutting exercise's marks: two concentric circles on a sheet at rest, the band the cut should run
/// between.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PatternSpec {
    /// The sheet (object index in the world).
    pub object: usize,
    /// The circles' centre, on the sheet at rest, world frame, mm.
    pub centre_mm: [f32; 3],
    /// The inner circle's radius, mm.
    pub inner_radius_mm: f32,
    /// The outer circle's radius, mm.
    pub outer_radius_mm: f32,
}

/// A validated `[exercise]` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExerciseSpec {
    /// Its name in reports.
    pub name: String,
    /// What it trains.
    pub kind: ExerciseKind,
    /// Time allowed from the first driven tick, s.
    pub time_limit_s: f64,
    /// Deepest press allowed at a target, mm (accurate-touch).
    pub depth_limit_mm: Option<f32>,
    /// Targets, in the order they must be touched (coordination, accurate-touch).
    pub targets: Vec<TargetSpec>,
    /// Samples to rank (stiffness-ranking), in world order.
    pub samples: Vec<SampleSpec>,
    /// The wound a suture exercise closes: its two edges, by object index (None: its gap is not scored).
    #[serde(default)]
    pub wound: Option<[usize; 2]>,
    /// A suture exercise tied off: it passes only with a secure knot read at the end (two throws or more,
    /// alternating hands: a square knot, a surgeon's knot), and a knot that came undone is an error.
    #[serde(default)]
    pub knot: bool,
    /// A pattern-cutting exercise's marked circles.
    #[serde(default)]
    pub pattern: Option<PatternSpec>,
}

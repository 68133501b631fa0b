//! Scripted hand trajectories for the simulated device, and their command-line form.
//!
//! Owns: [`HandScript`] (what the simulated hand tries to do, as a function of script time), the CLI names of
//! the scripts ([`ScriptKind`]) and their options ([`ScriptOptions`]). Everything is in the DEVICE frame, mm;
//! the server maps the device frame into the world. This file holds the scripts themselves and their
//! constants; where a script puts the hand and its jaws at a given time is in `trajectory`, the scripts' names,
//! options and parsing in `cli`.
//!
//! Must not: integrate physics (that is [`crate::hand_model`]) or keep time (the device passes script time in).

use std::fmt;
use std::sync::Arc;

use sinew_protocol::rt::LatestValue;

mod cli;
mod pose_path;
mod trajectory;

pub use cli::{ScriptError, ScriptKind, ScriptOptions, parse_vec3_mm};
pub use pose_path::{PoseKey, PosePath, PosePathError};

/// What the simulated hand does. Script time starts at 0 when the device is created.
#[derive(Clone)]
pub enum HandScript {
    /// Hold the stylus still at `position_mm`.
    Hold {
        /// Where, mm.
        position_mm: [f32; 3],
    },
    /// Start `approach_mm` above the surface point `at_mm`, descend along -z at constant speed for
    /// `descend_s` to `depth_mm` below it, then hold.
    Press {
        /// Surface point, mm.
        at_mm: [f32; 3],
        /// How far below the surface the hand aims, mm.
        depth_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
    },
    /// [`HandScript::Press`], then stroke sinusoidally along x: `x = at.x + stroke_mm * sin(2 pi t / period)`.
    PressAndStroke {
        /// Surface point, mm.
        at_mm: [f32; 3],
        /// How far below the surface the hand aims, mm.
        depth_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// Stroke amplitude: the target moves +/- this along x, mm.
        stroke_mm: f32,
        /// Period of one back-and-forth stroke, s.
        stroke_period_s: f32,
    },
    /// [`HandScript::Press`], then push deeper and back along -z: `depth + pulse_mm (1 - cos(2 pi t / period)) / 2`.
    PressAndPulse {
        /// Surface point, mm.
        at_mm: [f32; 3],
        /// How far below the surface the hand aims before pulsing, mm.
        depth_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// Extra depth at the peak of each pulse, mm.
        pulse_mm: f32,
        /// Period of one pulse, s.
        pulse_period_s: f32,
    },
    /// [`HandScript::Press`], close the jaws `settle_s` later (button 1 held, jaw angle 0), pull the grasped
    /// tissue by `pull_mm` over `pull_s` (a smooth cosine profile), hold `hold_s`, then open the jaws and stay.
    GraspPull {
        /// Surface point, mm.
        at_mm: [f32; 3],
        /// How far below the surface the jaws go before closing, mm.
        depth_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// Pause at depth before closing, s.
        settle_s: f32,
        /// Where the pull takes the hand from the closing point, mm.
        pull_mm: [f32; 3],
        /// Duration of the pull, s.
        pull_s: f32,
        /// Time held at the end of the pull before the jaws open, s.
        hold_s: f32,
    },
    /// [`HandScript::Press`], then hold button 1 (the cautery's current) while drawing the tip `stroke_mm`
    /// along +x over `stroke_s`; then let go of the button and hold.
    Cauterize {
        /// Surface point, mm.
        at_mm: [f32; 3],
        /// How far below the surface the tip goes, mm.
        depth_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// Length of the burn line along +x, mm.
        stroke_mm: f32,
        /// Duration of the line, s.
        stroke_s: f32,
    },
    /// Lower the tool to `height_mm` above the surface point (a scalpel's edge reaches below its origin, into
    /// the tissue) over `descend_s`, then draw it along `line_mm` over `line_s` at constant speed, and hold.
    CutLine {
        /// Surface point where the line starts, mm.
        at_mm: [f32; 3],
        /// Height of the tool origin above the surface while cutting, mm.
        height_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// The line, from its start, mm.
        line_mm: [f32; 3],
        /// Duration of the line, s.
        line_s: f32,
    },
    /// Lower the tool to `height_mm` above the surface point with the jaws open (scissors' blades reach below
    /// the hinge, into the tissue) over `descend_s`; then `snips` times: close the jaws (button 1 held, gripper
    /// at 0) for the first half of `snip_s`, open them and move `step_mm` along during the second half. Then
    /// hold, open.
    SnipLine {
        /// Surface point where the line starts, mm.
        at_mm: [f32; 3],
        /// Height of the tool origin (the hinge) above the surface while snipping, mm.
        height_mm: f32,
        /// Starting height above the surface, mm.
        approach_mm: f32,
        /// Duration of the descent, s.
        descend_s: f32,
        /// The move between two snips, mm.
        step_mm: [f32; 3],
        /// How many snips.
        snips: u32,
        /// Duration of one snip (close, then open and move), s.
        snip_s: f32,
    },
    /// The target is set from outside (a test, a replay); the hand holds the last target it saw.
    Follow(Arc<LatestValue<[f32; 3]>>),
    /// Follow keyframes of the whole pose and the jaws ([`PosePath`]: a planned path, such as a needle
    /// driver's turn through tissue), then hold the last.
    Path(Arc<PosePath>),
}

/// Height of the tool origin above the surface during `cut-line`, mm: a scalpel's edge starts 1 mm below its
/// origin by default, so it reaches from 0.5 mm above the surface into the tissue.
pub const CUT_LINE_HEIGHT_MM: f32 = 1.5;

/// Height of the hinge above the surface during `snip-line`, mm: 12 mm blades opened 40 degrees then reach
/// 5.5 mm into the tissue and take a 3.7 mm bite each snip.
pub const SNIP_LINE_HEIGHT_MM: f32 = 6.0;

/// The move between two snips of `snip-line`, mm (a snip's bite overlaps the last).
pub const SNIP_STEP_MM: f32 = 3.0;

/// One snip of `snip-line`, s: the blades are held shut for the first half (0.4 s, four times their 90 ms
/// slew, so they shut even while a server cutting the tissue runs at a quarter of real time), then open while
/// the hand moves on.
pub const SNIP_PERIOD_S: f32 = 0.8;

/// Opening of a scripted gripper's open jaws, rad (40 degrees).
pub const SCRIPT_JAW_OPEN_RAD: f32 = 0.698;

/// What a scripted hand does with the instrument's jaws: the buttons held and the gripper opening.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptGrip {
    /// Button bits held (bit 0 closes a grasper driven by a button).
    pub buttons: u32,
    /// Gripper opening, rad (0 closed; a grasper driven by the angle closes below its threshold).
    pub jaw_angle_rad: f32,
}

impl fmt::Debug for HandScript {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HandScript::Hold { position_mm } => f
                .debug_struct("Hold")
                .field("position_mm", position_mm)
                .finish(),
            HandScript::Press {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
            } => f
                .debug_struct("Press")
                .field("at_mm", at_mm)
                .field("depth_mm", depth_mm)
                .field("approach_mm", approach_mm)
                .field("descend_s", descend_s)
                .finish(),
            HandScript::PressAndStroke {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
                stroke_mm,
                stroke_period_s,
            } => f
                .debug_struct("PressAndStroke")
                .field("at_mm", at_mm)
                .field("depth_mm", depth_mm)
                .field("approach_mm", approach_mm)
                .field("descend_s", descend_s)
                .field("stroke_mm", stroke_mm)
                .field("stroke_period_s", stroke_period_s)
                .finish(),
            HandScript::PressAndPulse {
                at_mm,
                depth_mm,
                pulse_mm,
                pulse_period_s,
                ..
            } => f
                .debug_struct("PressAndPulse")
                .field("at_mm", at_mm)
                .field("depth_mm", depth_mm)
                .field("pulse_mm", pulse_mm)
                .field("pulse_period_s", pulse_period_s)
                .finish(),
            HandScript::GraspPull {
                at_mm,
                depth_mm,
                pull_mm,
                ..
            } => f
                .debug_struct("GraspPull")
                .field("at_mm", at_mm)
                .field("depth_mm", depth_mm)
                .field("pull_mm", pull_mm)
                .finish(),
            HandScript::Cauterize {
                at_mm,
                depth_mm,
                stroke_mm,
                ..
            } => f
                .debug_struct("Cauterize")
                .field("at_mm", at_mm)
                .field("depth_mm", depth_mm)
                .field("stroke_mm", stroke_mm)
                .finish(),
            HandScript::CutLine { at_mm, line_mm, .. } => f
                .debug_struct("CutLine")
                .field("at_mm", at_mm)
                .field("line_mm", line_mm)
                .finish(),
            HandScript::SnipLine {
                at_mm,
                step_mm,
                snips,
                ..
            } => f
                .debug_struct("SnipLine")
                .field("at_mm", at_mm)
                .field("step_mm", step_mm)
                .field("snips", snips)
                .finish(),
            HandScript::Follow(target) => f.debug_tuple("Follow").field(&target.peek()).finish(),
            HandScript::Path(path) => f
                .debug_struct("Path")
                .field("keys", &path.keys().len())
                .field("end_s", &path.end_s())
                .finish(),
        }
    }
}

//! Scripted hand trajectories for the simulated device, and their command-line form.
//!
//! Owns: [`HandScript`] (what the simulated hand tries to do, as a function of script time), the CLI names of
//! the scripts ([`ScriptKind`]) and their options ([`ScriptOptions`]). Everything is in the DEVICE frame, mm;
//! the server maps the device frame into the world.
//!
//! Must not: integrate physics (that is [`crate::hand_model`]) or keep time (the device passes script time in).

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use sinew_protocol::rt::LatestValue;
use thiserror::Error;

use crate::hand_model::HandTarget;

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
}

/// Height of the tool origin above the surface during `cut-line`, mm: a scalpel's edge starts 1 mm below its
/// origin by default, so it reaches from 0.5 mm above the surface into the tissue.
pub const CUT_LINE_HEIGHT_MM: f32 = 1.5;

/// Height of the hinge above the surface during `snip-line`, mm: 12 mm blades opened 40 degrees then reach
/// 5.5 mm into the tissue and take a 3.7 mm bite each snip.
pub const SNIP_LINE_HEIGHT_MM: f32 = 6.0;

/// The move between two snips of `snip-line`, mm (a snip's bite overlaps the last).
pub const SNIP_STEP_MM: f32 = 3.0;

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
        }
    }
}

/// The vertical part of a press: start above, descend at constant speed, hold at depth.
fn press_target(
    at_mm: [f32; 3],
    depth_mm: f32,
    approach_mm: f32,
    descend_s: f32,
    t_s: f64,
) -> HandTarget {
    let top_z = at_mm[2] + approach_mm;
    let bottom_z = at_mm[2] - depth_mm;
    let descend_s = f64::from(descend_s);
    if descend_s.is_nan() || descend_s <= 0.0 || t_s >= descend_s {
        return HandTarget::at_rest([at_mm[0], at_mm[1], bottom_z]);
    }
    let t_s = t_s.max(0.0);
    let fraction = (t_s / descend_s) as f32;
    let speed_mm_s = (bottom_z - top_z) / descend_s as f32;
    HandTarget {
        position_mm: [at_mm[0], at_mm[1], top_z + (bottom_z - top_z) * fraction],
        velocity_mm_s: [0.0, 0.0, speed_mm_s],
    }
}

impl HandScript {
    /// The target at script time `t_s`, or `None` when the script has nothing new (a [`HandScript::Follow`]
    /// whose mailbox is empty or momentarily busy): the device then keeps its last target.
    ///
    /// Real-time contract: no allocation, never blocks, never panics.
    pub fn target(&self, t_s: f64) -> Option<HandTarget> {
        match self {
            HandScript::Hold { position_mm } => Some(HandTarget::at_rest(*position_mm)),
            HandScript::Press {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
            } => Some(press_target(
                *at_mm,
                *depth_mm,
                *approach_mm,
                *descend_s,
                t_s,
            )),
            HandScript::PressAndStroke {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
                stroke_mm,
                stroke_period_s,
            } => {
                let mut target = press_target(*at_mm, *depth_mm, *approach_mm, *descend_s, t_s);
                let stroke_t_s = t_s - f64::from(*descend_s);
                if stroke_t_s > 0.0 && *stroke_period_s > 0.0 {
                    let omega_rad_s = std::f64::consts::TAU / f64::from(*stroke_period_s);
                    let phase_rad = omega_rad_s * stroke_t_s;
                    let stroke_mm = f64::from(*stroke_mm);
                    target.position_mm[0] = at_mm[0] + (stroke_mm * phase_rad.sin()) as f32;
                    target.velocity_mm_s[0] = (stroke_mm * omega_rad_s * phase_rad.cos()) as f32;
                }
                Some(target)
            }
            HandScript::PressAndPulse {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
                pulse_mm,
                pulse_period_s,
            } => {
                let mut target = press_target(*at_mm, *depth_mm, *approach_mm, *descend_s, t_s);
                let pulse_t_s = t_s - f64::from(*descend_s);
                if pulse_t_s > 0.0 && *pulse_period_s > 0.0 {
                    let omega_rad_s = std::f64::consts::TAU / f64::from(*pulse_period_s);
                    let phase_rad = omega_rad_s * pulse_t_s;
                    let half = f64::from(*pulse_mm) / 2.0;
                    target.position_mm[2] -= (half * (1.0 - phase_rad.cos())) as f32;
                    target.velocity_mm_s[2] = -(half * omega_rad_s * phase_rad.sin()) as f32;
                }
                Some(target)
            }
            HandScript::GraspPull {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
                settle_s,
                pull_mm,
                pull_s,
                ..
            } => {
                let mut target = press_target(*at_mm, *depth_mm, *approach_mm, *descend_s, t_s);
                let pull_t_s = t_s - f64::from(*descend_s + *settle_s) - GRIP_LEAD_S;
                if pull_t_s > 0.0 {
                    let duration_s = f64::from(pull_s.max(1e-3));
                    let phase = (pull_t_s / duration_s).min(1.0);
                    let share = (0.5 * (1.0 - (std::f64::consts::PI * phase).cos())) as f32;
                    let rate = if phase < 1.0 {
                        (0.5 * std::f64::consts::PI / duration_s
                            * (std::f64::consts::PI * phase).sin()) as f32
                    } else {
                        0.0
                    };
                    for ((x, v), pull) in target
                        .position_mm
                        .iter_mut()
                        .zip(target.velocity_mm_s.iter_mut())
                        .zip(pull_mm)
                    {
                        *x += pull * share;
                        *v = pull * rate;
                    }
                }
                Some(target)
            }
            HandScript::Cauterize {
                at_mm,
                depth_mm,
                approach_mm,
                descend_s,
                stroke_mm,
                stroke_s,
            } => {
                let mut target = press_target(*at_mm, *depth_mm, *approach_mm, *descend_s, t_s);
                let stroke_t_s = t_s - f64::from(*descend_s);
                if stroke_t_s > 0.0 {
                    let duration_s = f64::from(stroke_s.max(1e-3));
                    let share = (stroke_t_s / duration_s).min(1.0) as f32;
                    target.position_mm[0] = at_mm[0] + stroke_mm * share;
                    target.velocity_mm_s[0] = if share < 1.0 {
                        (f64::from(*stroke_mm) / duration_s) as f32
                    } else {
                        0.0
                    };
                }
                Some(target)
            }
            HandScript::CutLine {
                at_mm,
                height_mm,
                approach_mm,
                descend_s,
                line_mm,
                line_s,
            } => {
                let mut target = press_target(*at_mm, -height_mm, *approach_mm, *descend_s, t_s);
                let line_t_s = t_s - f64::from(*descend_s);
                if line_t_s > 0.0 {
                    let duration_s = f64::from(line_s.max(1e-3));
                    let share = (line_t_s / duration_s).min(1.0) as f32;
                    for ((x, v), d) in target
                        .position_mm
                        .iter_mut()
                        .zip(target.velocity_mm_s.iter_mut())
                        .zip(line_mm)
                    {
                        *x += d * share;
                        *v = if share < 1.0 {
                            (f64::from(*d) / duration_s) as f32
                        } else {
                            0.0
                        };
                    }
                }
                Some(target)
            }
            HandScript::SnipLine {
                at_mm,
                height_mm,
                approach_mm,
                descend_s,
                step_mm,
                snips,
                snip_s,
            } => {
                let mut target = press_target(*at_mm, -height_mm, *approach_mm, *descend_s, t_s);
                let snip_t = snip_phase(t_s, *descend_s, *snips, *snip_s);
                if let Some((done, moving)) = snip_t {
                    // `done` snips finished moving; in the second half of a snip the hand moves one step.
                    let share = done as f32 + moving;
                    let rate = if moving > 0.0 && moving < 1.0 {
                        2.0 / snip_s.max(1e-3)
                    } else {
                        0.0
                    };
                    for ((x, v), d) in target
                        .position_mm
                        .iter_mut()
                        .zip(target.velocity_mm_s.iter_mut())
                        .zip(step_mm)
                    {
                        *x += d * share;
                        *v = d * rate;
                    }
                }
                Some(target)
            }
            HandScript::Follow(mailbox) => mailbox.peek().map(HandTarget::at_rest),
        }
    }

    /// What the hand does with the jaws at script time `t_s`: open, except a [`HandScript::GraspPull`] between
    /// its closing and its release. Real-time: no allocation.
    pub fn grip(&self, t_s: f64) -> ScriptGrip {
        let open = ScriptGrip {
            buttons: 0,
            jaw_angle_rad: SCRIPT_JAW_OPEN_RAD,
        };
        match self {
            HandScript::GraspPull {
                descend_s,
                settle_s,
                pull_s,
                hold_s,
                ..
            } => {
                let close_s = f64::from(*descend_s + *settle_s);
                let open_s = close_s + GRIP_LEAD_S + f64::from(*pull_s + *hold_s);
                if (close_s..open_s).contains(&t_s) {
                    ScriptGrip {
                        buttons: 1,
                        jaw_angle_rad: 0.0,
                    }
                } else {
                    open
                }
            }
            HandScript::Cauterize {
                descend_s,
                stroke_s,
                ..
            } => {
                let on = f64::from(*descend_s)..f64::from(*descend_s + *stroke_s);
                ScriptGrip {
                    buttons: u32::from(on.contains(&t_s)),
                    ..open
                }
            }
            HandScript::SnipLine {
                descend_s,
                snips,
                snip_s,
                ..
            } => match snip_phase(t_s, *descend_s, *snips, *snip_s) {
                Some((done, moving)) if done < *snips && moving == 0.0 => ScriptGrip {
                    buttons: 1,
                    jaw_angle_rad: 0.0,
                },
                _ => open,
            },
            _ => open,
        }
    }

    /// Where the stylus starts: the target at time 0, or the origin for a [`HandScript::Follow`] with no target.
    pub fn start_mm(&self) -> [f32; 3] {
        self.target(0.0).map_or([0.0; 3], |t| t.position_mm)
    }
}

/// Where a `snip-line` is at script time `t_s`: `None` before its first snip, else the snips whose move is
/// done and the share (0 to 1) of the current snip's move made (0 while the jaws are closing: the first half
/// of each snip). After the last snip: `(snips, 0.0)`.
fn snip_phase(t_s: f64, descend_s: f32, snips: u32, snip_s: f32) -> Option<(u32, f32)> {
    let since_s = t_s - f64::from(descend_s);
    if since_s.is_nan() || since_s < 0.0 {
        return None;
    }
    let period_s = f64::from(snip_s.max(1e-3));
    let k = (since_s / period_s).floor();
    if k >= f64::from(snips) {
        return Some((snips, 0.0));
    }
    let phase = since_s / period_s - k;
    let moving = ((phase - 0.5) * 2.0).clamp(0.0, 1.0) as f32;
    Some((k as u32, moving))
}

/// A scripted pull starts this long after the jaws close, s: the grasp takes hold on the closing tick, the
/// jaws are drawn shut.
const GRIP_LEAD_S: f64 = 0.2;

/// A script or option given on the command line that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ScriptError {
    /// Not one of the script names.
    #[error(
        "unknown script `{0}`: expected one of hold, press, press-stroke, grasp-pull, cauterize, cut-line, snip-line"
    )]
    UnknownScript(String),
    /// A vector option is not three comma-separated numbers.
    #[error("`{0}` is not a vector `x,y,z` of three finite numbers (mm)")]
    BadVector(String),
    /// A numeric option is out of its domain.
    #[error("script option {option} = {value} is invalid: {reason}")]
    BadOption {
        /// Option name.
        option: &'static str,
        /// The value given.
        value: f32,
        /// Why.
        reason: &'static str,
    },
}

/// The scripts that can be chosen by name (`--script`). [`HandScript::Follow`] has no CLI form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScriptKind {
    /// `hold`: [`HandScript::Hold`] at `at_mm`.
    Hold,
    /// `press`: [`HandScript::Press`].
    Press,
    /// `press-stroke`: [`HandScript::PressAndStroke`].
    PressStroke,
    /// `grasp-pull`: [`HandScript::GraspPull`] (press, close, pull up by `depth + 5` mm over 1 s, hold 2 s, open).
    GraspPull,
    /// `cauterize`: [`HandScript::Cauterize`] (press, then button 1 held along a `stroke_mm` line over 2 s).
    Cauterize,
    /// `cut-line`: [`HandScript::CutLine`] (down to [`CUT_LINE_HEIGHT_MM`] above the surface, then a
    /// `stroke_mm` line along +y over 2 s).
    CutLine,
    /// `snip-line`: [`HandScript::SnipLine`] (hinge down to [`SNIP_LINE_HEIGHT_MM`] above the surface, then
    /// `stroke_mm` / 3 mm snips 3 mm apart along +y, 0.4 s each).
    SnipLine,
}

impl ScriptKind {
    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            ScriptKind::Hold => "hold",
            ScriptKind::Press => "press",
            ScriptKind::PressStroke => "press-stroke",
            ScriptKind::GraspPull => "grasp-pull",
            ScriptKind::Cauterize => "cauterize",
            ScriptKind::CutLine => "cut-line",
            ScriptKind::SnipLine => "snip-line",
        }
    }

    /// Build the script with `options`, checking them.
    pub fn build(self, options: &ScriptOptions) -> Result<HandScript, ScriptError> {
        options.validate()?;
        let o = options;
        Ok(match self {
            ScriptKind::Hold => HandScript::Hold {
                position_mm: o.at_mm,
            },
            ScriptKind::Press => HandScript::Press {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
            },
            ScriptKind::PressStroke => HandScript::PressAndStroke {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                stroke_mm: o.stroke_mm,
                stroke_period_s: o.stroke_period_s,
            },
            ScriptKind::GraspPull => HandScript::GraspPull {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                settle_s: 0.3,
                pull_mm: [0.0, 0.0, o.depth_mm + 5.0],
                pull_s: 1.0,
                hold_s: 2.0,
            },
            ScriptKind::Cauterize => HandScript::Cauterize {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                stroke_mm: o.stroke_mm,
                stroke_s: 2.0,
            },
            ScriptKind::CutLine => HandScript::CutLine {
                at_mm: o.at_mm,
                height_mm: CUT_LINE_HEIGHT_MM,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                line_mm: [0.0, o.stroke_mm, 0.0],
                line_s: 2.0,
            },
            ScriptKind::SnipLine => HandScript::SnipLine {
                at_mm: o.at_mm,
                height_mm: SNIP_LINE_HEIGHT_MM,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                step_mm: [0.0, SNIP_STEP_MM, 0.0],
                snips: (o.stroke_mm / SNIP_STEP_MM).ceil().max(1.0) as u32,
                snip_s: 0.4,
            },
        })
    }
}

impl FromStr for ScriptKind {
    type Err = ScriptError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "hold" => Ok(ScriptKind::Hold),
            "press" => Ok(ScriptKind::Press),
            "press-stroke" | "press_stroke" => Ok(ScriptKind::PressStroke),
            "grasp-pull" | "grasp_pull" => Ok(ScriptKind::GraspPull),
            "cauterize" => Ok(ScriptKind::Cauterize),
            "cut-line" | "cut_line" => Ok(ScriptKind::CutLine),
            "snip-line" | "snip_line" => Ok(ScriptKind::SnipLine),
            other => Err(ScriptError::UnknownScript(other.to_owned())),
        }
    }
}

impl fmt::Display for ScriptKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Options shared by the named scripts (device frame, mm and s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptOptions {
    /// Surface point to press at (or the point to hold), mm.
    pub at_mm: [f32; 3],
    /// Depth below the surface, mm.
    pub depth_mm: f32,
    /// Starting height above the surface, mm.
    pub approach_mm: f32,
    /// Descent duration, s.
    pub descend_s: f32,
    /// Stroke amplitude along x, mm.
    pub stroke_mm: f32,
    /// Stroke period, s.
    pub stroke_period_s: f32,
}

impl Default for ScriptOptions {
    /// Press 5 mm at the device origin from 20 mm above over 2 s; stroke +/- 10 mm every 2 s.
    fn default() -> Self {
        Self {
            at_mm: [0.0; 3],
            depth_mm: 5.0,
            approach_mm: 20.0,
            descend_s: 2.0,
            stroke_mm: 10.0,
            stroke_period_s: 2.0,
        }
    }
}

impl ScriptOptions {
    /// Check every option's domain.
    pub fn validate(&self) -> Result<(), ScriptError> {
        if !self.at_mm.iter().all(|c| c.is_finite()) {
            return Err(ScriptError::BadVector(format!("{:?}", self.at_mm)));
        }
        let checks: [(&'static str, f32, bool, &'static str); 5] = [
            (
                "depth_mm",
                self.depth_mm,
                self.depth_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "approach_mm",
                self.approach_mm,
                self.approach_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "descend_s",
                self.descend_s,
                self.descend_s >= 0.0,
                "must be >= 0",
            ),
            (
                "stroke_mm",
                self.stroke_mm,
                self.stroke_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "stroke_period_s",
                self.stroke_period_s,
                self.stroke_period_s > 0.0,
                "must be > 0",
            ),
        ];
        for (option, value, ok, reason) in checks {
            if !(ok && value.is_finite()) {
                return Err(ScriptError::BadOption {
                    option,
                    value,
                    reason,
                });
            }
        }
        Ok(())
    }
}

/// Parse `x,y,z` (mm) as given to `--at-mm`.
pub fn parse_vec3_mm(text: &str) -> Result<[f32; 3], ScriptError> {
    let bad = || ScriptError::BadVector(text.to_owned());
    let mut out = [0.0f32; 3];
    let mut parts = text.split(',');
    for slot in &mut out {
        let value: f32 = parts
            .next()
            .ok_or_else(bad)?
            .trim()
            .parse()
            .map_err(|_| bad())?;
        if !value.is_finite() {
            return Err(bad());
        }
        *slot = value;
    }
    if parts.next().is_some() {
        return Err(bad());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn z(script: &HandScript, t_s: f64) -> f32 {
        script.target(t_s).unwrap().position_mm[2]
    }

    #[test]
    fn press_starts_above_and_reaches_depth() {
        let script = ScriptKind::Press
            .build(&ScriptOptions {
                at_mm: [1.0, 2.0, 3.0],
                depth_mm: 4.0,
                approach_mm: 10.0,
                descend_s: 1.0,
                ..ScriptOptions::default()
            })
            .unwrap();
        assert_eq!(script.start_mm(), [1.0, 2.0, 13.0]);
        assert!(
            (z(&script, 0.5) - 6.0).abs() < 1e-4,
            "halfway from 13 to -1"
        );
        assert!(script.target(0.5).unwrap().velocity_mm_s[2] < 0.0);
        assert_eq!(
            script.target(1.0).unwrap(),
            HandTarget::at_rest([1.0, 2.0, -1.0])
        );
        assert_eq!(
            script.target(100.0).unwrap(),
            HandTarget::at_rest([1.0, 2.0, -1.0])
        );
    }

    #[test]
    fn hold_holds() {
        let script = ScriptKind::Hold
            .build(&ScriptOptions {
                at_mm: [5.0, -5.0, 1.0],
                ..ScriptOptions::default()
            })
            .unwrap();
        for t_s in [0.0, 0.3, 10.0, 1e6] {
            assert_eq!(
                script.target(t_s).unwrap(),
                HandTarget::at_rest([5.0, -5.0, 1.0])
            );
        }
    }

    #[test]
    fn press_stroke_strokes_along_x_at_depth() {
        let options = ScriptOptions::default();
        let script = ScriptKind::PressStroke.build(&options).unwrap();
        let after_s = f64::from(options.descend_s);
        let quarter_s = f64::from(options.stroke_period_s) / 4.0;
        let peak = script.target(after_s + quarter_s).unwrap();
        assert!((peak.position_mm[0] - options.stroke_mm).abs() < 1e-3);
        assert!((peak.position_mm[2] + options.depth_mm).abs() < 1e-4);
        for i in 0..1000 {
            let x = script
                .target(after_s + i as f64 * 0.01)
                .unwrap()
                .position_mm[0];
            assert!(x.abs() <= options.stroke_mm + 1e-3);
        }
    }

    #[test]
    fn follow_holds_the_last_target() {
        let mailbox = Arc::new(LatestValue::new());
        let script = HandScript::Follow(mailbox.clone());
        assert_eq!(script.target(0.0), None);
        assert_eq!(script.start_mm(), [0.0; 3]);
        mailbox.store([1.0, 2.0, 3.0]);
        assert_eq!(
            script.target(1.0).unwrap(),
            HandTarget::at_rest([1.0, 2.0, 3.0])
        );
        assert_eq!(
            script.target(2.0).unwrap(),
            HandTarget::at_rest([1.0, 2.0, 3.0])
        );
    }

    #[test]
    fn cli_forms_parse_and_bad_ones_are_named() {
        assert_eq!("press".parse::<ScriptKind>(), Ok(ScriptKind::Press));
        assert_eq!(
            "press-stroke".parse::<ScriptKind>(),
            Ok(ScriptKind::PressStroke)
        );
        assert_eq!("hold".parse::<ScriptKind>(), Ok(ScriptKind::Hold));
        let err = "poke".parse::<ScriptKind>().unwrap_err();
        assert!(err.to_string().contains("poke"));
        assert_eq!(parse_vec3_mm("1, -2.5,3"), Ok([1.0, -2.5, 3.0]));
        for bad in ["", "1,2", "1,2,3,4", "a,b,c", "1,NaN,2", "1,inf,2"] {
            assert!(parse_vec3_mm(bad).is_err(), "{bad:?} accepted");
        }
        let err = ScriptKind::Press
            .build(&ScriptOptions {
                depth_mm: -1.0,
                ..ScriptOptions::default()
            })
            .unwrap_err();
        assert!(err.to_string().contains("depth_mm"));
    }

    #[test]
    fn grasp_pull_closes_at_depth_pulls_then_opens() {
        let script = ScriptKind::GraspPull
            .build(&ScriptOptions {
                depth_mm: 2.0,
                descend_s: 1.0,
                ..ScriptOptions::default()
            })
            .unwrap();
        assert_eq!(script.grip(0.5).buttons, 0);
        assert!((z(&script, 1.2) + 2.0).abs() < 1e-6);
        let closed = script.grip(1.35);
        assert_eq!((closed.buttons, closed.jaw_angle_rad), (1, 0.0));
        // Pulled up by depth + 5 mm once the pull is over, still closed while held.
        assert!((z(&script, 2.6) - 5.0).abs() < 1e-4);
        assert_eq!(script.grip(4.4).buttons, 1);
        assert_eq!(script.grip(4.6).buttons, 0);
        assert!((z(&script, 5.0) - 5.0).abs() < 1e-4);
    }

    #[test]
    fn snip_line_closes_in_place_then_opens_and_moves_one_step() {
        let script = ScriptKind::SnipLine
            .build(&ScriptOptions {
                at_mm: [0.0, 0.0, 0.0],
                stroke_mm: 9.0,
                descend_s: 1.0,
                ..ScriptOptions::default()
            })
            .unwrap();
        let y = |t: f64| script.target(t).unwrap().position_mm[1];
        // Descending: open, at the start.
        assert_eq!(script.grip(0.5).buttons, 0);
        assert!((z(&script, 1.0) - SNIP_LINE_HEIGHT_MM).abs() < 1e-4);
        // First snip: closed and still for 0.2 s, then open while moving 3 mm.
        assert_eq!(script.grip(1.1).buttons, 1);
        assert_eq!(y(1.1), 0.0);
        assert_eq!(script.grip(1.3).buttons, 0);
        assert!((y(1.3) - 1.5).abs() < 1e-4);
        assert!((y(1.4) - SNIP_STEP_MM).abs() < 1e-4);
        // Three snips for 9 mm; then open and still at 9 mm.
        assert_eq!(script.grip(1.9).buttons, 1);
        assert!((y(1.9) - 2.0 * SNIP_STEP_MM).abs() < 1e-4);
        assert_eq!(script.grip(2.5).buttons, 0);
        assert!((y(3.0) - 9.0).abs() < 1e-4);
        assert_eq!(script.target(3.0).unwrap().velocity_mm_s, [0.0; 3]);
    }
}

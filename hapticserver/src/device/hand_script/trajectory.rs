//! Where a [`HandScript`] puts the hand and its jaws at a given script time: the target position and
//! velocity, and the grip (buttons and jaw opening).
//!
//! Owns: [`HandScript::target`], [`HandScript::grip`] and [`HandScript::start_mm`], and the shared pieces of
//! the scripts' motion (the vertical press, the phase of a snip line, the lead between closing the jaws and
//! pulling).
//!
//! Must not: integrate physics (that is [`crate::hand_model`]), keep time (script time is passed in), parse
//! or validate options (that is the parent's `cli`), allocate, block or panic.

use crate::hand_model::HandTarget;

use super::{HandScript, SCRIPT_JAW_OPEN_RAD, ScriptGrip};

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
            HandScript::Path(path) => Some(path.target(t_s)),
        }
    }

    /// The stylus's orientation at script time `t_s`, unit quaternion (x, y, z, w): a [`HandScript::Path`]'s,
    /// upright (identity) for every other script. Real-time: no allocation.
    pub fn orientation_xyzw(&self, t_s: f64) -> [f32; 4] {
        match self {
            HandScript::Path(path) => path.orientation_xyzw(t_s),
            _ => [0.0, 0.0, 0.0, 1.0],
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
            HandScript::Path(path) => {
                let buttons = path.buttons(t_s);
                ScriptGrip {
                    buttons,
                    jaw_angle_rad: if buttons & 1 != 0 {
                        0.0
                    } else {
                        SCRIPT_JAW_OPEN_RAD
                    },
                }
            }
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

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use sinew_protocol::rt::LatestValue;

    use super::*;
    use crate::hand_script::{
        SNIP_LINE_HEIGHT_MM, SNIP_PERIOD_S, SNIP_STEP_MM, ScriptKind, ScriptOptions,
    };

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
        // First snip: closed and still for half a period (0.4 s), then open while moving 3 mm.
        assert_eq!(SNIP_PERIOD_S, 0.8);
        assert_eq!(script.grip(1.1).buttons, 1);
        assert_eq!(script.grip(1.35).buttons, 1);
        assert_eq!(y(1.35), 0.0);
        assert_eq!(script.grip(1.6).buttons, 0);
        assert!((y(1.6) - 1.5).abs() < 1e-4);
        assert!((y(1.8) - SNIP_STEP_MM).abs() < 1e-4);
        // Three snips for 9 mm; then open and still at 9 mm.
        assert_eq!(script.grip(2.7).buttons, 1);
        assert!((y(2.7) - 2.0 * SNIP_STEP_MM).abs() < 1e-4);
        assert_eq!(script.grip(3.5).buttons, 0);
        assert!((y(4.0) - 9.0).abs() < 1e-4);
        assert_eq!(script.target(4.0).unwrap().velocity_mm_s, [0.0; 3]);
    }
}

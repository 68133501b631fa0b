//! What an instructor watches for, drawn over the scene: each participant's id, role, mode, round trip and
//! force, an arrow at each tool for the force the tissue exerts on it (scaled, coloured by how close it is to
//! the device's limit), the running exercise's live score, and a ring round each of its targets (or a
//! suture's marks) where the world file puts them: green once hit, yellow for the next, white after.
//!
//! Owns: turning a replica (tool states, 60 Hz) and the server's stats (1 Hz) into text lines and arrows
//! ([`InstructorOverlay::build`], plain data, tested without a GPU), and drawing them on a kiss3d window or
//! offscreen surface ([`draw_overlay`]).
//!
//! Must not: keep state between frames, or read anything but the replica and the stats.

use std::sync::Arc;

use kiss3d::color::Color;
use kiss3d::glamx::{Vec2, Vec3};
use kiss3d::text::Font;
use kiss3d::window::Window;
use sinew_protocol::{DeviceStats, ServerStats};

use crate::replica::SceneReplica;

/// Arrow length per newton of tool force, mm (a 3.3 N device limit draws as 33 mm, the pad's half width).
pub const ARROW_MM_PER_N: f32 = 10.0;

/// Forces below this draw no arrow, newtons (a resting tool).
pub const ARROW_MIN_FORCE_N: f32 = 0.02;

/// Text size, pixels.
const TEXT_PX: f32 = 20.0;
/// Text line spacing, pixels.
const LINE_PX: f32 = 24.0;
/// Text margin from the image's top-left corner, pixels.
const MARGIN_PX: f32 = 10.0;
/// Arrow line width, pixels.
const ARROW_WIDTH_PX: f32 = 4.0;

/// Colour of text and arrows, linear RGB 0-1.
pub type Rgb = [f32; 3];

/// Plain text.
pub const TEXT_RGB: Rgb = [0.92, 0.93, 0.95];
/// A force whose device limit is unknown (no hello yet).
pub const UNKNOWN_LIMIT_RGB: Rgb = [0.55, 0.70, 0.95];

/// One line of text.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlayLine {
    /// The text.
    pub text: String,
    /// Its colour.
    pub rgb: Rgb,
}

/// One tool's force arrow, world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceArrow {
    /// Tool index.
    pub tool: u16,
    /// Where it starts: the tool's origin, mm.
    pub from_mm: [f32; 3],
    /// Where it ends: the origin plus the force times [`ARROW_MM_PER_N`], mm.
    pub to_mm: [f32; 3],
    /// The force magnitude, newtons.
    pub force_n: f32,
    /// The force over the device's limit (None: limit unknown).
    pub fraction_of_limit: Option<f32>,
    /// Its colour ([`limit_rgb`]).
    pub rgb: Rgb,
}

/// A ring round one of the exercise's targets, in the world's x-y plane (targets lie on surfaces facing up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetRing {
    /// Its centre: the target's mark on the tissue at rest, world mm.
    pub centre_mm: [f32; 3],
    /// Its radius: the target's, mm.
    pub radius_mm: f32,
    /// [`HIT_RGB`] once hit, [`NEXT_RGB`] for the next to hit, [`TEXT_RGB`] after it.
    pub rgb: Rgb,
}

/// A target hit.
pub const HIT_RGB: Rgb = [0.20, 0.85, 0.30];
/// The next target to hit.
pub const NEXT_RGB: Rgb = [0.95, 0.85, 0.15];
/// Straight strokes per target ring.
const RING_STROKES: usize = 32;

/// The overlay of one frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InstructorOverlay {
    /// Text lines, top to bottom: the scene, one per participant, the exercise.
    pub lines: Vec<OverlayLine>,
    /// One arrow per active tool pushed by a force above [`ARROW_MIN_FORCE_N`].
    pub arrows: Vec<ForceArrow>,
    /// One ring per target of the running exercise, in its order.
    pub targets: Vec<TargetRing>,
}

/// Green well under the limit, through yellow at half of it, to red at 90% and beyond.
pub fn limit_rgb(fraction_of_limit: Option<f32>) -> Rgb {
    let Some(f) = fraction_of_limit else {
        return UNKNOWN_LIMIT_RGB;
    };
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let green = [0.20, 0.85, 0.30];
    let yellow = [0.95, 0.85, 0.15];
    let red = [0.95, 0.15, 0.12];
    let mix = |a: Rgb, b: Rgb, t: f32| std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t);
    if f <= 0.5 {
        mix(green, yellow, f / 0.5)
    } else {
        mix(yellow, red, ((f - 0.5) / 0.4).min(1.0))
    }
}

impl InstructorOverlay {
    /// The overlay for the replica's newest tool states and the newest stats (None: none arrived yet, so
    /// modes, round trips, limits and the score are unknown and said to be).
    pub fn build(replica: &SceneReplica, stats: Option<&ServerStats>) -> Self {
        let mut lines = Vec::new();
        let states = replica.tool_states();
        let scene_line = match stats {
            Some(s) => format!(
                "{}  t {:.1} s  tick p99 {:.2} ms",
                replica.scene(),
                states.sim_time_s.max(s.sim_time_s),
                s.tick_p99_us / 1000.0
            ),
            None => format!(
                "{}  t {:.1} s  (no server stats yet)",
                replica.scene(),
                states.sim_time_s
            ),
        };
        lines.push(OverlayLine {
            text: scene_line,
            rgb: TEXT_RGB,
        });
        let mut arrows = Vec::new();
        for info in replica.tools() {
            let device =
                stats.and_then(|s| s.devices.iter().find(|d| d.device_id == info.device_id));
            let state = states.tools.iter().find(|s| s.tool == info.tool);
            let force = state.map_or([0.0; 3], |s| s.force_n);
            let force_n = force.iter().map(|c| c * c).sum::<f32>().sqrt();
            let limit_n = device.map_or(0.0, |d| d.force_limit_n);
            let fraction = (limit_n > 0.0).then(|| force_n / limit_n);
            let active = state.is_some_and(|s| s.active);
            let rgb = limit_rgb(fraction);
            lines.push(OverlayLine {
                text: participant_line(&info.device_id, &info.name, active, force_n, device),
                rgb: if active { rgb } else { TEXT_RGB },
            });
            if let Some(state) = state
                && state.active
                && force_n.is_finite()
                && force_n >= ARROW_MIN_FORCE_N
            {
                arrows.push(ForceArrow {
                    tool: info.tool,
                    from_mm: state.position_mm,
                    to_mm: std::array::from_fn(|i| {
                        state.position_mm[i] + force[i] * ARROW_MM_PER_N
                    }),
                    force_n,
                    fraction_of_limit: fraction,
                    rgb,
                });
            }
        }
        let mut targets = Vec::new();
        if let Some(exercise) = stats.and_then(|s| s.exercise.as_ref()) {
            let next = exercise.targets.iter().position(|t| !t.hit);
            targets.extend(
                exercise
                    .targets
                    .iter()
                    .enumerate()
                    .map(|(i, target)| TargetRing {
                        centre_mm: target.at_mm,
                        radius_mm: target.radius_mm,
                        rgb: if target.hit {
                            HIT_RGB
                        } else if Some(i) == next {
                            NEXT_RGB
                        } else {
                            TEXT_RGB
                        },
                    }),
            );
            let status = if exercise.completed {
                "  done"
            } else if exercise.timed_out {
                "  time up"
            } else {
                ""
            };
            lines.push(OverlayLine {
                text: format!(
                    "exercise {}: score {:.0}  {}/{}  errors {}  {:.1} s{status}",
                    exercise.kind,
                    exercise.score,
                    exercise.hits,
                    exercise.total,
                    exercise.errors,
                    exercise.time_s
                ),
                rgb: TEXT_RGB,
            });
        }
        Self {
            lines,
            arrows,
            targets,
        }
    }
}

/// `left (surgeon, probe): moderated  rtt 2.1 ms  1.02/3.30 N  contact  touches 3`.
fn participant_line(
    device_id: &str,
    tool: &str,
    active: bool,
    force_n: f32,
    device: Option<&DeviceStats>,
) -> String {
    let Some(d) = device else {
        return format!("{device_id} (surgeon, {tool}): {force_n:.2} N");
    };
    if !active {
        return format!("{device_id} (surgeon, {tool}): not connected");
    }
    let mode = if d.moderated { "moderated" } else { "direct" };
    let rtt = if d.last_round_trip_us == 0 {
        "rtt ?".to_owned()
    } else {
        format!("rtt {:.1} ms", f64::from(d.last_round_trip_us) / 1000.0)
    };
    let limit = if d.force_limit_n > 0.0 {
        format!("{force_n:.2}/{:.2} N", d.force_limit_n)
    } else {
        format!("{force_n:.2} N")
    };
    let t = &d.training;
    format!(
        "{device_id} (surgeon, {tool}): {mode}  {rtt}  {limit}  {}  touches {}",
        if t.skill_state.is_empty() {
            "-"
        } else {
            t.skill_state.as_str()
        },
        t.contacts
    )
}

fn color(rgb: Rgb) -> Color {
    Color::new(rgb[0], rgb[1], rgb[2], 1.0)
}

/// Queue the overlay on `window` for its next frame: text top-left, arrows as 3D lines with a head, target
/// rings as 3D polygons.
pub fn draw_overlay(window: &mut Window, overlay: &InstructorOverlay, font: &Arc<Font>) {
    for (i, line) in overlay.lines.iter().enumerate() {
        window.draw_text(
            &line.text,
            Vec2::new(MARGIN_PX, MARGIN_PX + LINE_PX * i as f32),
            TEXT_PX,
            font,
            color(line.rgb),
        );
    }
    for ring in &overlay.targets {
        let centre = Vec3::from(ring.centre_mm);
        let at = |k: usize| {
            let a = std::f32::consts::TAU * k as f32 / RING_STROKES as f32;
            centre + Vec3::new(a.cos(), a.sin(), 0.0) * ring.radius_mm
        };
        for k in 0..RING_STROKES {
            window.draw_line(at(k), at(k + 1), color(ring.rgb), ARROW_WIDTH_PX, false);
        }
    }
    for arrow in &overlay.arrows {
        let from = Vec3::from(arrow.from_mm);
        let to = Vec3::from(arrow.to_mm);
        let c = color(arrow.rgb);
        window.draw_line(from, to, c, ARROW_WIDTH_PX, false);
        // Head: two strokes back from the tip, a quarter of the shaft long, in a plane holding the shaft.
        let shaft = to - from;
        let length = shaft.length();
        if length <= f32::EPSILON {
            continue;
        }
        let along = shaft / length;
        let side = along.any_orthonormal_vector();
        let back = -along * (0.25 * length);
        for sign in [-1.0, 1.0] {
            window.draw_line(
                to,
                to + back + side * (sign * 0.12 * length),
                c,
                ARROW_WIDTH_PX,
                false,
            );
        }
    }
}

//! The scripted stitch's plan, second part: the hand-off. With the needle's tip out of the far skin, the
//! needle driver opens its ratchet and leaves the needle in the tissue, held by its holes ([`release`]); the
//! grasper comes to the tip from outside the needle's curve, closes on it, and draws the needle on along its
//! own curve until its tail has left the last hole, then lifts it clear ([`regrasp_and_draw`]), as a surgeon
//! takes the needle at its tip on the far side and follows its curve out.
//!
//! Owns: the hand-off's keyframes and timing. Where the needle lies when let go is an input: a rehearsal of the
//! pass finds it (`stitch_script`), as a surgeon looks before reaching.
//!
//! Must not: step a simulation or open sessions.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sinew_server::interaction::suture::NeedleArc;

use crate::stitch_plan::HandKeys;

/// The driver's ratchet opens while its first button is held (`needle_driver.rs`).
pub const DRIVER_OPEN: u32 = 1;
/// A grasper's jaws close while its first button is held.
pub const GRASPER_CLOSED: u32 = 1;

/// The driver stays this long with its jaws open before it moves, s (the needle's load fades from the hand
/// over the jaws' opening).
const OPEN_S: f64 = 0.4;
/// Then it rises this far straight up, mm, over [`RISE_S`].
const RISE_MM: f32 = 15.0;
const RISE_S: f64 = 0.6;
/// And waits here, world, mm, out of the grasper's way along the wound, its jaws still open.
const DRIVER_ASIDE_MM: [f32; 3] = [-15.0, -25.0, 25.0];
const ASIDE_S: f64 = 1.0;

/// The grasper's capsule (1.5 mm radius) closes this far from the needle's tip, out from the needle's centre,
/// mm: its side 0.3 mm off the wire's centre line.
pub const BESIDE_TIP_MM: f32 = 1.8;
/// It comes down on the tip from this high above, mm.
const APPROACH_MM: f32 = 20.0;
/// It draws the needle along its curve this much less than the needle's sweep, degrees: the tail then stands
/// that far past where the tip was let go, clear of the last hole.
const DRAW_SHORT_OF_SWEEP_DEG: f32 = 10.0;
/// It draws this fast, degrees a second (as the driver turned).
const DRAW_DEG_PER_S: f32 = 40.0;
/// A keyframe every this many degrees of the draw.
const DRAW_STEP_DEG: f32 = 2.0;
/// Then it lifts the needle this far straight up, mm, over [`LIFT_S`] (along the tail's way out).
const LIFT_MM: f32 = 6.0;
const LIFT_S: f64 = 0.6;

/// Open the driver's ratchet at `from_s`, leave the needle and wait aside, jaws open. Returns when the driver
/// is aside, s.
pub fn release(driver: &mut HandKeys, from_s: f64) -> f64 {
    let at = driver.world_from_tool().translation.vector;
    driver.hold(from_s, DRIVER_OPEN);
    let risen_s = from_s + OPEN_S + RISE_S;
    driver.hold(from_s + OPEN_S, DRIVER_OPEN);
    driver.reach(risen_s, at + Vector3::new(0.0, 0.0, RISE_MM), DRIVER_OPEN);
    let aside_s = risen_s + ASIDE_S;
    driver.reach(aside_s, Vector3::from(DRIVER_ASIDE_MM), DRIVER_OPEN);
    aside_s
}

/// When the grasper's hand-off is done.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegraspTimes {
    /// The grasper's jaws close on the tip, s.
    pub closed_s: f64,
    /// The needle has been drawn out along its curve and lifted, s.
    pub drawn_s: f64,
}

/// The grasper, from where it waits, to the tip of the needle let go at `world_from_needle` (from `from_s`),
/// closing on it, then drawing the needle on along its curve and lifting it clear.
pub fn regrasp_and_draw(
    grasper: &mut HandKeys,
    from_s: f64,
    world_from_needle: &Isometry3<f32>,
    arc: &NeedleArc,
) -> RegraspTimes {
    let centre = (world_from_needle * Point3::origin()).coords;
    let tip = (world_from_needle * Point3::from(arc.tip().point_mm)).coords;
    let outward = (tip - centre).normalize();
    let at_tip = tip + outward * BESIDE_TIP_MM;
    let waiting = grasper.world_from_tool();
    grasper.hold(from_s, 0);
    let over_s = from_s + 1.5;
    grasper.reach(over_s, at_tip + Vector3::new(0.0, 0.0, APPROACH_MM), 0);
    let down_s = over_s + 1.5;
    grasper.reach(down_s, at_tip, GRASPER_CLOSED);
    let closed_s = down_s + 0.3;
    grasper.hold(closed_s + 0.3, GRASPER_CLOSED);
    // The tip goes on along the needle frame's +z turn: the grasper turns with it about the needle's centre.
    let axis = world_from_needle * Vector3::z_axis();
    let draw_deg = arc.sweep_rad().to_degrees() - DRAW_SHORT_OF_SWEEP_DEG;
    let steps = (draw_deg / DRAW_STEP_DEG).round() as usize;
    let start_s = grasper.end_s();
    let held = Isometry3::from_parts(at_tip.into(), waiting.rotation);
    for k in 1..=steps {
        let deg = k as f32 * DRAW_STEP_DEG;
        let turn = UnitQuaternion::from_axis_angle(&axis, deg.to_radians());
        let pose = Isometry3::from_parts(
            (centre + turn * (held.translation.vector - centre)).into(),
            turn * held.rotation,
        );
        grasper.pose(
            start_s + f64::from(deg / DRAW_DEG_PER_S),
            &pose,
            GRASPER_CLOSED,
        );
    }
    let at = grasper.world_from_tool().translation.vector;
    let lifted_s = grasper.end_s() + LIFT_S;
    grasper.reach(
        lifted_s,
        at + Vector3::new(0.0, 0.0, LIFT_MM),
        GRASPER_CLOSED,
    );
    let drawn_s = lifted_s + 0.3;
    grasper.hold(drawn_s, GRASPER_CLOSED);
    RegraspTimes { closed_s, drawn_s }
}

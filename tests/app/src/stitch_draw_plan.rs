//! The scripted stitch's plan, last part: the draw. The needle driver, its jaws open since it let the needle
//! go, comes down beside the thread's free end and closes on it ([`take_free_end`]); then both hands draw the
//! ends crossed over the wound, each to the other side, and hold ([`tighten`]): the grasper the needle's end,
//! the driver the free end. The draw is planned as far as a 3 N pull takes the world's skin: the hands stop
//! there, as the wound tests' force-limited hands do.
//!
//! Owns: [`DrawPlan`] and the draw's keyframes. Where the thread's free end lies and where the needle's tail
//! is are inputs: a rehearsal of the hand-off finds them (`stitch_script`).
//!
//! Must not: step a simulation or open sessions.

use nalgebra::Vector3;

use crate::stitch_hand_off_plan::{DRIVER_OPEN, GRASPER_CLOSED};
use crate::stitch_plan::HandKeys;

/// How both hands draw the stitch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawPlan {
    /// How far each end is drawn toward its target on the other side (20 mm out, 15 mm up, 3 mm apart along
    /// the wound), as a share of the way: what a 3 N pull takes on the world's skin.
    pub share: f32,
    /// How long the draw takes, s.
    pub draw_s: f64,
    /// How long the hands then hold, s.
    pub hold_s: f64,
}

impl DrawPlan {
    /// The wound's: 60% of the way over 4 s, held 3 s. Through firm hands on virtual time (the
    /// scripted-stitch test), the grasper drawing the needle's end and the driver the free end: half the way
    /// left a 1.90 mm gap at 1.8 and 1.4 N, 65% met the edges (0.00 mm) at 2.9 and 2.7 N, 80% pressed them
    /// 0.43 mm into each other at 5.4 N.
    pub fn wound() -> Self {
        Self {
            share: 0.6,
            draw_s: 4.0,
            hold_s: 3.0,
        }
    }
}

/// The driver's jaws close this far beside the thread along the wound, mm (0.2 mm jaws, 0.3 mm off).
const BESIDE_THREAD_MM: f32 = 0.5;
/// They come down on it from this high above, mm.
const APPROACH_MM: f32 = 20.0;

/// The driver, from where it waits with its jaws open (from `from_s`), down beside the thread at `node_mm`
/// (world) and closing on it. Returns when its jaws have closed, s.
pub fn take_free_end(driver: &mut HandKeys, from_s: f64, node_mm: &Vector3<f32>) -> f64 {
    let at = node_mm + Vector3::new(0.0, BESIDE_THREAD_MM, 0.0);
    driver.hold(from_s, DRIVER_OPEN);
    let over_s = from_s + 1.5;
    driver.reach(
        over_s,
        at + Vector3::new(0.0, 0.0, APPROACH_MM),
        DRIVER_OPEN,
    );
    let down_s = over_s + 1.5;
    driver.reach(down_s, at, 0);
    down_s + 0.3
}

/// Both hands draw from `from_s`: the grasper's needle, whose tail (where the thread is swaged) is at
/// `tail_mm` (world), toward the side the needle went in on (-`exit_side` along x), the driver's free end toward
/// the side it came out on. Returns when the stitch has been held to its end, s.
pub fn tighten(
    driver: &mut HandKeys,
    grasper: &mut HandKeys,
    from_s: f64,
    tail_mm: &Vector3<f32>,
    exit_side: f32,
    draw: &DrawPlan,
) -> f64 {
    let draw_to_s = from_s + draw.draw_s;
    let end_s = draw_to_s + draw.hold_s;
    // The grasper moves the needle whole: its tail goes the share of the way to its target.
    let tail_to = Vector3::new(-exit_side * 20.0, -3.0, 15.0);
    let grasper_at = grasper.world_from_tool().translation.vector;
    grasper.hold(from_s, GRASPER_CLOSED);
    grasper.reach(
        draw_to_s,
        grasper_at + (tail_to - tail_mm) * draw.share,
        GRASPER_CLOSED,
    );
    grasper.hold(end_s, GRASPER_CLOSED);
    let free_to = Vector3::new(exit_side * 20.0, 3.0, 15.0);
    let driver_at = driver.world_from_tool().translation.vector;
    driver.hold(from_s, 0);
    driver.reach(draw_to_s, driver_at + (free_to - driver_at) * draw.share, 0);
    driver.hold(end_s, 0);
    end_s
}

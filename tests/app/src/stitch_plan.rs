//! The scripted stitch's plan, first part: where a stitch goes, the keyframes a planned hand is given, and the
//! needle driver's pass. The driver (left hand) rolls its needle along its own curve about the needle's
//! centre, in through one edge, out of its face, into the other's and up, until the tip stands out of the far
//! skin ([`pass_path`]); the hand-off and the draw follow (`stitch_hand_off_plan`, `stitch_draw_plan`). While
//! the tip goes in, the driver's aim leads the needle along its tip ([`PUSH_MM`]): a compliant hand lags its
//! aim, and a lagging tip turns past the puncture cone before it pushes hard enough, so the hand pushes the
//! needle in as a surgeon does.
//!
//! Owns: [`StitchSite`], [`HandKeys`], [`pass_path`] and the pass's timing. Paths are in each device's frame
//! (the world less the device's origin), for [`hapticserver::HandScript::Path`].
//!
//! Must not: step a simulation or open sessions (it plans; others run the plan).

use anyhow::Context as _;
use hapticserver::hand_script::{PoseKey, PosePath};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sinew_server::world::{InstrumentSpec, World};

/// Where a stitch is laid: the needle's centre as it turns (world, mm), above the wound's middle, and the
/// axis it turns about (along the wound).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StitchSite {
    /// The needle's centre during the pass, world, mm.
    pub centre_mm: [f32; 3],
    /// The skin's top around the wound, world z, mm (the needle enters it `LEAD_IN_DEG` after the pass starts).
    pub skin_z_mm: f32,
}

impl StitchSite {
    /// The wound of `worlds/suture.toml`: along y at x = 0, its skin's top on z = 0; the needle's
    /// centre 3 mm above it (a 10.7 mm needle then bites 7.4 mm deep through each edge's face).
    pub const WOUND: StitchSite = StitchSite {
        centre_mm: [0.0, 0.0, 3.0],
        skin_z_mm: 0.0,
    };
}

/// One planned hand's keyframes, built in time order: poses given in the world, kept in its device's frame.
#[derive(Debug, Clone)]
pub struct HandKeys {
    /// The device's origin, world, mm.
    origin_mm: Vector3<f32>,
    keys: Vec<PoseKey>,
}

impl HandKeys {
    /// A hand on the device at `origin_mm` (world), resting at `world_from_tool` from time 0 with `buttons`.
    pub fn new(origin_mm: Vector3<f32>, world_from_tool: &Isometry3<f32>, buttons: u32) -> Self {
        let mut hand = Self {
            origin_mm,
            keys: Vec::new(),
        };
        hand.pose(0.0, world_from_tool, buttons);
        hand
    }

    /// Reach `world_from_tool` at `t_s` (straight from the last keyframe), holding `buttons` from then on.
    pub fn pose(&mut self, t_s: f64, world_from_tool: &Isometry3<f32>, buttons: u32) {
        let p = world_from_tool.translation.vector - self.origin_mm;
        let q = world_from_tool.rotation.as_ref().coords;
        self.keys.push(PoseKey {
            t_s,
            position_mm: [p.x, p.y, p.z],
            orientation_xyzw: [q.x, q.y, q.z, q.w],
            buttons,
        });
    }

    /// Reach `world_mm` at `t_s` at the last keyframe's orientation, holding `buttons` from then on.
    pub fn reach(&mut self, t_s: f64, world_mm: Vector3<f32>, buttons: u32) {
        let pose = Isometry3::from_parts(world_mm.into(), self.world_from_tool().rotation);
        self.pose(t_s, &pose, buttons);
    }

    /// Stay at the last keyframe's pose until `t_s`, holding `buttons` from then on (at the last keyframe's
    /// own time, its buttons change).
    pub fn hold(&mut self, t_s: f64, buttons: u32) {
        if let Some(last) = self.keys.last_mut().filter(|k| k.t_s == t_s) {
            last.buttons = buttons;
            return;
        }
        let pose = self.world_from_tool();
        self.pose(t_s, &pose, buttons);
    }

    /// The last keyframe's pose, world (the identity before any).
    pub fn world_from_tool(&self) -> Isometry3<f32> {
        self.keys.last().map_or_else(Isometry3::identity, |k| {
            let [x, y, z, w] = k.orientation_xyzw;
            let rotation = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let p = Vector3::from(k.position_mm) + self.origin_mm;
            Isometry3::from_parts(p.into(), rotation)
        })
    }

    /// When the last keyframe is reached, s.
    pub fn end_s(&self) -> f64 {
        self.keys.last().map_or(0.0, |k| k.t_s)
    }

    /// The path through the keyframes (an error names a keyframe out of time order).
    pub fn path(&self) -> anyhow::Result<PosePath> {
        Ok(PosePath::new(self.keys.clone())?)
    }
}

/// The pass is entered this far before the tip meets the skin, degrees.
const LEAD_IN_DEG: f32 = 8.0;
/// The driver turns this fast through the tissue, degrees a second.
const TURN_DEG_PER_S: f32 = 40.0;
/// The driver turns on this far past where its tip, on the planned path, comes out of the far skin: the tip
/// then stands 3-4 mm out for the grasper (20 degrees of a 10.7 mm needle), and a hand lagging its aim by a
/// few degrees still brings it out.
const TIP_OUT_DEG: f32 = 25.0;
/// The hands wait this long at their start, s (the scene comes up; the hand settles).
const SETTLE_S: f64 = 1.5;
/// The driver holds still this long after the pass, s.
const AFTER_PASS_S: f64 = 0.5;
/// A keyframe every this many degrees of the turn.
const TURN_STEP_DEG: f32 = 2.0;
/// How far ahead along the needle's tip the hand aims while the tip goes in, mm: a compliant hand lags its aim
/// by the force over its grip's stiffness (1.5 N of puncture over a firm 1 N/mm grip is 1.5 mm), and a tip
/// that lags turns past the puncture cone before it pushes hard enough. A surgeon pushes the needle in.
pub const PUSH_MM: f32 = 2.0;
/// The push is held this far past the tip's meeting the skin, degrees of turn.
const PUSH_HOLD_DEG: f32 = 20.0;
/// Then eased out over this much more, degrees.
const PUSH_RAMP_OUT_DEG: f32 = 20.0;

/// The driver's pass: its path and when the turn ends.
#[derive(Debug, Clone)]
pub struct PassPlan {
    /// The driver's keyframes through the pass (it holds the last).
    pub driver: HandKeys,
    /// When the driver is still again after the pass, s.
    pub done_s: f64,
    /// The driver's pose then, world.
    pub end_pose: Isometry3<f32>,
    /// Which side of the wound the needle comes out on (x's sign).
    pub exit_side: f32,
}

/// The needle driver's pass for `world`'s needle driver (its first tool with one), on `site`.
pub fn pass_path(world: &World, site: &StitchSite) -> anyhow::Result<PassPlan> {
    let (tool, spec) = world
        .tools
        .iter()
        .find_map(|t| match &t.instrument {
            InstrumentSpec::NeedleDriver(spec) => Some((t, *spec)),
            _ => None,
        })
        .context("the world has no needle driver")?;
    let origin = Vector3::from(tool.device_origin_in_world_mm);
    let tool_from_needle = spec.tool_from_needle();
    let centre_tool = (tool_from_needle * Point3::origin()).coords;
    let tip_tool = (tool_from_needle * Point3::from(spec.arc.tip().point_mm)).coords;
    let tip_dir_tool = tool_from_needle * spec.arc.tip().tangent;
    let centre = Vector3::from(site.centre_mm);
    // The needle's plane square to the wound (the driver's shaft level), turned about y through the centre.
    let base = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2);
    let pose_at = |turn_rad: f32| {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), turn_rad) * base;
        Isometry3::from_parts((centre - rotation * centre_tool).into(), rotation)
    };
    let tip_at = |turn_rad: f32| {
        let pose = pose_at(turn_rad);
        (
            (pose * Point3::from(tip_tool)).coords,
            pose.rotation * tip_dir_tool,
        )
    };
    // Where the tip reaches the skin's plane going down, and the way to turn to go on.
    let surface_z = site.skin_z_mm;
    let entry = (0..7200)
        .map(|k| -std::f32::consts::PI + k as f32 * 0.05f32.to_radians())
        .find(|&turn| {
            let (tip, dir) = tip_at(turn);
            (tip.z - surface_z).abs() < 0.05 && dir.z < 0.0
        })
        .context("the needle's tip never reaches the skin going down")?;
    let (tip, dir) = tip_at(entry);
    let ahead = tip_at(entry + 0.01).0 - tip;
    let sign = ahead.dot(&dir).signum();
    let start = entry - sign * LEAD_IN_DEG.to_radians();
    // Where the tip, turning on, comes back up through the skin's plane: the far edge's top.
    let exit = (1..7200)
        .map(|k| entry + sign * k as f32 * 0.05f32.to_radians())
        .find(|&turn| {
            let (tip, dir) = tip_at(turn);
            (tip.z - surface_z).abs() < 0.05 && dir.z > 0.0
        })
        .context("the needle's tip never comes back out of the skin")?;
    let turn_deg = ((exit - start) * sign).to_degrees() + TIP_OUT_DEG;
    let mut driver = HandKeys::new(origin, &pose_at(start), 0);
    driver.hold(SETTLE_S, 0);
    let steps = (turn_deg / TURN_STEP_DEG).round() as usize;
    for k in 1..=steps {
        let turned_deg = k as f32 * TURN_STEP_DEG;
        let t_s = SETTLE_S + f64::from(turned_deg / TURN_DEG_PER_S);
        let turn = start + sign * turned_deg.to_radians();
        let mut pose = pose_at(turn);
        // The hand leads the needle in along its tip (module doc): the push ramps in over the lead-in, holds
        // while the tip should pop, and ramps out.
        let past_entry_deg = turned_deg - LEAD_IN_DEG;
        let share = if past_entry_deg < 0.0 {
            turned_deg / LEAD_IN_DEG
        } else if past_entry_deg < PUSH_HOLD_DEG {
            1.0
        } else {
            (1.0 - (past_entry_deg - PUSH_HOLD_DEG) / PUSH_RAMP_OUT_DEG).max(0.0)
        };
        if share > 0.0 {
            let (_, dir) = tip_at(turn);
            pose.translation.vector += dir * (PUSH_MM * share);
        }
        driver.pose(t_s, &pose, 0);
    }
    let turn_deg = steps as f32 * TURN_STEP_DEG;
    let end_pose = pose_at(start + sign * turn_deg.to_radians());
    let turned_s = SETTLE_S + f64::from(turn_deg / TURN_DEG_PER_S);
    let done_s = turned_s + AFTER_PASS_S;
    driver.pose(done_s, &end_pose, 0);
    // The needle goes in on the side the tip first meets and comes out on the other.
    let exit_side = -tip.x.signum();
    Ok(PassPlan {
        driver,
        done_s,
        end_pose,
        exit_side,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use sinew_server::world::load_world;

    fn wound() -> World {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../worlds/suture.toml");
        load_world(&path).unwrap()
    }

    #[test]
    fn the_pass_turns_the_needle_about_its_centre_into_the_skin_and_round() {
        let world = wound();
        let pass = pass_path(&world, &StitchSite::WOUND).unwrap();
        let path = pass.driver.path().unwrap();
        let keys = path.keys();
        // The tip comes out of the far skin about 155 degrees past the lead-in's start (its 8 degrees, the
        // 147 degrees a 10.7 mm needle turning 3 mm above the skin runs under it), and the turn goes 25 on.
        let turned_deg = (pass.done_s - 0.5 - 1.5) * 40.0;
        assert!((175.0..=185.0).contains(&turned_deg), "{turned_deg}");
        // Every keyframe turns about y: the needle's plane stays square to the wound.
        let q = |k: &PoseKey| {
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                k.orientation_xyzw[3],
                k.orientation_xyzw[0],
                k.orientation_xyzw[1],
                k.orientation_xyzw[2],
            ))
        };
        let first = q(&keys[0]);
        for k in keys {
            let relative = q(k) * first.inverse();
            if let Some(axis) = relative.axis() {
                assert!(axis.y.abs() > 0.999, "{axis:?}");
            }
        }
        assert!(path.target(0.0).position_mm.iter().all(|c| c.is_finite()));
        assert!(pass.exit_side == 1.0 || pass.exit_side == -1.0);
    }
}

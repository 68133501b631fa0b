//! The scripted stitch's plan: the simulated surgeons' pose paths for one stitch across a wound, as a surgeon
//! lays it. The needle driver (left hand) rolls its needle along its own curve about the needle's centre,
//! through both edges and out ([`pass_path`]); the grasper (right hand) waits aside, comes down on the thread
//! past the entry and takes it ([`stitch_paths`]); then both draw the ends crossed over the wound, each to the
//! other side, and hold (the draw is planned as far as a 3 N pull takes the world's skin: the hands stop
//! there, as the wound tests' force-limited hands do). While the tip goes in, the driver's aim leads the
//! needle along its tip ([`PUSH_MM`]): a compliant hand lags its aim, and a lagging tip turns past the
//! puncture cone before it pushes hard enough, so the hand pushes the needle in as a surgeon does.
//!
//! Owns: [`StitchSite`], [`pass_path`], [`stitch_paths`] and the timing of the stitch's phases. Paths are in
//! each device's frame (the world less the device's origin), for [`hapticserver::HandScript::Path`]. Where
//! the grasper takes the thread is an input: a rehearsal of the pass finds it (the tests' drill on virtual
//! time), as a surgeon looks before reaching.
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
    /// The wound of `worlds/suture_wound.toml`: along y at x = 0, its skin's top on z = 0; the needle's
    /// centre 3 mm above it (a 10.7 mm needle then bites 7.4 mm deep through each edge's face).
    pub const WOUND: StitchSite = StitchSite {
        centre_mm: [0.0, 0.0, 3.0],
        skin_z_mm: 0.0,
    };
}

/// The pass is entered this far before the tip meets the skin, degrees.
const LEAD_IN_DEG: f32 = 8.0;
/// The driver turns this fast through the tissue, degrees a second.
const TURN_DEG_PER_S: f32 = 40.0;
/// The driver turns this far past the lead-in: the tail leaves the fourth hole about 340 degrees on.
const TURN_DEG: f32 = 360.0;
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
    pub keys: Vec<PoseKey>,
    /// When the driver is still again after the pass, s.
    pub done_s: f64,
    /// The driver's pose then, world.
    pub end_pose: Isometry3<f32>,
    /// Which side of the wound the needle comes out on (x's sign): the grasper's end is drawn toward it.
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
    let key = |t_s: f64, pose: &Isometry3<f32>| {
        let q = pose.rotation.as_ref().coords;
        let p = pose.translation.vector - origin;
        PoseKey {
            t_s,
            position_mm: [p.x, p.y, p.z],
            orientation_xyzw: [q.x, q.y, q.z, q.w],
            buttons: 0,
        }
    };
    let mut keys = vec![key(0.0, &pose_at(start)), key(SETTLE_S, &pose_at(start))];
    let steps = (TURN_DEG / TURN_STEP_DEG).round() as usize;
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
        keys.push(key(t_s, &pose));
    }
    let end_pose = pose_at(start + sign * TURN_DEG.to_radians());
    let turned_s = SETTLE_S + f64::from(TURN_DEG / TURN_DEG_PER_S);
    let done_s = turned_s + AFTER_PASS_S;
    keys.push(key(done_s, &end_pose));
    // The needle goes in on the side the tip first meets and comes out on the other.
    let exit_side = -tip.x.signum();
    Ok(PassPlan {
        keys,
        done_s,
        end_pose,
        exit_side,
    })
}

/// How the grasper takes the thread and both hands draw the stitch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawPlan {
    /// Where the grasper's jaws take the thread, world, mm.
    pub grasp_mm: [f32; 3],
    /// How far each hand draws toward the other side (20 mm out, 15 mm up, 3 mm apart along the wound), as a
    /// share of the way: what a 3 N pull takes on the world's skin.
    pub share: f32,
    /// How long the draw takes, s.
    pub draw_s: f64,
    /// How long the hands then hold, s.
    pub hold_s: f64,
}

impl DrawPlan {
    /// The wound's: half the way, which closes it at about 3 N through compliant hands (the wound tests'
    /// stiff, force-limited hands stopped at 40-47% of the way; 55% drawn through firm hands met the edges at
    /// 3.2 N, 65% pressed them 0.33 mm into each other at 4.8 N), over 4 s, held 3 s.
    pub fn wound(grasp_mm: [f32; 3]) -> Self {
        Self {
            grasp_mm,
            share: 0.5,
            draw_s: 4.0,
            hold_s: 3.0,
        }
    }
}

/// Where the grasper waits during the pass, world, mm.
const GRASPER_PARK_MM: [f32; 3] = [30.0, 0.0, 30.0];
/// The grasper comes down on the thread from this high above it, mm.
const GRASP_APPROACH_MM: f32 = 20.0;
/// The grasper's capsule (1.5 mm radius) stops this far beside the thread along x, mm: its side 0.3 mm off.
const GRASP_BESIDE_MM: f32 = 1.8;

/// The grasper's path (the world's grasper: its first tool with one), and the driver's draw appended to
/// `pass`: the grasper parked until the pass is done, down onto the thread and closed, then both hands
/// draw crossed and hold. Returns (driver, grasper) paths and when the stitch ends, s.
pub fn stitch_paths(
    world: &World,
    pass: &PassPlan,
    draw: &DrawPlan,
) -> anyhow::Result<(PosePath, PosePath, f64)> {
    let tool = world
        .tools
        .iter()
        .find(|t| matches!(t.instrument, InstrumentSpec::Grasper(_)))
        .context("the world has no grasper")?;
    let origin = Vector3::from(tool.device_origin_in_world_mm);
    let along_y = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f32::consts::FRAC_PI_2);
    let q = along_y.as_ref().coords;
    let key = |t_s: f64, world_mm: Vector3<f32>, closed: bool| {
        let p = world_mm - origin;
        PoseKey {
            t_s,
            position_mm: [p.x, p.y, p.z],
            orientation_xyzw: [q.x, q.y, q.z, q.w],
            buttons: u32::from(closed),
        }
    };
    let grasp = Vector3::from(draw.grasp_mm) + Vector3::new(GRASP_BESIDE_MM, 0.0, 0.0);
    let above = grasp + Vector3::new(0.0, 0.0, GRASP_APPROACH_MM);
    let park = Vector3::from(GRASPER_PARK_MM);
    let t0 = pass.done_s;
    let (over_s, down_s, close_s) = (t0 + 1.5, t0 + 3.0, t0 + 3.3);
    let draw_from_s = close_s + 0.3;
    let draw_to_s = draw_from_s + draw.draw_s;
    let end_s = draw_to_s + draw.hold_s;
    let side = pass.exit_side;
    let grasper_to = grasp + (Vector3::new(side * 20.0, 3.0, 15.0) - grasp) * draw.share;
    let grasper = PosePath::new(vec![
        key(0.0, park, false),
        key(t0, park, false),
        key(over_s, above, false),
        key(down_s, grasp, false),
        key(close_s, grasp, true),
        key(draw_from_s, grasp, true),
        key(draw_to_s, grasper_to, true),
        key(end_s, grasper_to, true),
    ])?;
    let driver_origin = world
        .tools
        .iter()
        .find(|t| matches!(t.instrument, InstrumentSpec::NeedleDriver(_)))
        .map(|t| Vector3::from(t.device_origin_in_world_mm))
        .context("the world has no needle driver")?;
    let from = pass.end_pose.translation.vector;
    let driver_to = from + (Vector3::new(-side * 20.0, -3.0, 15.0) - from) * draw.share;
    let mut keys = pass.keys.clone();
    let last = *keys.last().context("an empty pass")?;
    let mut at = |t_s: f64, world_mm: Vector3<f32>| {
        let p = world_mm - driver_origin;
        keys.push(PoseKey {
            t_s,
            position_mm: [p.x, p.y, p.z],
            ..last
        });
    };
    at(draw_from_s, from);
    at(draw_to_s, driver_to);
    at(end_s, driver_to);
    Ok((PosePath::new(keys)?, grasper, end_s))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use sinew_server::world::load_world;

    fn wound() -> World {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../worlds/suture_wound.toml");
        load_world(&path).unwrap()
    }

    #[test]
    fn the_pass_turns_the_needle_about_its_centre_into_the_skin_and_round() {
        let world = wound();
        let pass = pass_path(&world, &StitchSite::WOUND).unwrap();
        let path = PosePath::new(pass.keys.clone()).unwrap();
        assert!((pass.done_s - (1.5 + 9.0 + 0.5)).abs() < 1e-9);
        // Every keyframe turns about y: the needle's plane stays square to the wound.
        let q = |k: &PoseKey| {
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                k.orientation_xyzw[3],
                k.orientation_xyzw[0],
                k.orientation_xyzw[1],
                k.orientation_xyzw[2],
            ))
        };
        let first = q(&pass.keys[0]);
        for k in &pass.keys {
            let relative = q(k) * first.inverse();
            if let Some(axis) = relative.axis() {
                assert!(axis.y.abs() > 0.999, "{axis:?}");
            }
        }
        assert!(path.target(0.0).position_mm.iter().all(|c| c.is_finite()));
        assert!(pass.exit_side == 1.0 || pass.exit_side == -1.0);
    }
}

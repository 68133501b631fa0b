//! The scripted stitch as the simulated surgeons' scripts: the paths of [`crate::stitch_plan`],
//! [`crate::stitch_hand_off_plan`] and [`crate::stitch_draw_plan`], each stage planned after a rehearsal of
//! the stages before it on virtual time, through the real server tick and device loops ([`crate::drill`]), has
//! shown where things lie, as a surgeon looks before reaching: where the needle was let go (for the grasper
//! to take its tip), then where the thread's free end lies once the needle is drawn through (for the driver
//! to take it, 15 mm past its last hole) and where the needle's tail is. `sinew demo` runs it for a world with
//! a needle driver and a grasper; the scripted-stitch test checks the whole stitch the same way.
//!
//! Owns: [`StitchScripts`], [`stitch_scripts`], [`stitch_site`] (where a world's stitch goes) and
//! [`stitch_devices`] (the hands that run it). Must not: open sessions (the rehearsals are on virtual time).

use std::sync::Arc;

use anyhow::Context as _;
use hapticserver::{HandPreset, HandScript, ModePolicy};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sinew_server::interaction::suture::NeedleHolder;
use sinew_server::server_tick::ServerTick;
use sinew_server::world::{InstrumentSpec, World};

use crate::drill::{DrillDevice, Link, run_drill_observed};
use crate::stitch_draw_plan::{DrawPlan, take_free_end, tighten};
use crate::stitch_hand_off_plan::{regrasp_and_draw, release};
use crate::stitch_plan::{HandKeys, StitchSite, pass_path};

/// The hands a stitch is planned for: firm (a surgeon pushing a needle in grips the driver firmly; the plan's
/// push is sized for it).
pub const STITCH_HAND: HandPreset = HandPreset::Firm;

/// The driver takes the thread this far past its last hole toward the free end, mm.
const TAKE_PAST_LAST_HOLE_MM: f32 = 15.0;
/// Where the grasper waits during the pass, world, mm.
const GRASPER_PARK_MM: [f32; 3] = [30.0, 0.0, 30.0];

/// Both surgeons' scripts for one stitch.
#[derive(Debug, Clone)]
pub struct StitchScripts {
    /// The needle driver's device and script.
    pub driver: (String, HandScript),
    /// The grasper's device and script.
    pub grasper: (String, HandScript),
    /// When the stitch is drawn tight and held to its end, s of script time.
    pub end_s: f64,
    /// Where the rehearsal found the needle's tip once let go, world, mm.
    pub tip_mm: [f32; 3],
    /// Where the rehearsal found the thread's free end for the driver, world, mm.
    pub free_end_mm: [f32; 3],
}

/// Where `world`'s stitch goes: the needle's centre 3 mm above the middle of its objects' top (the wound of
/// `worlds/suture.toml` lies there, between its two blocks).
pub fn stitch_site(world: &World) -> anyhow::Result<StitchSite> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for object in &world.objects {
        for p in &object.mesh.positions_mm {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    anyhow::ensure!(lo[0].is_finite(), "the world has no tissue to stitch");
    Ok(StitchSite {
        centre_mm: [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), hi[2] + 3.0],
        skin_z_mm: hi[2],
    })
}

/// The two simulated surgeons of a stitch, on a LAN-like link with direct rendering.
pub fn stitch_devices(
    driver: (String, HandScript),
    grasper: (String, HandScript),
) -> [DrillDevice; 2] {
    let device = |(id, script): (String, HandScript)| DrillDevice {
        id,
        hand: STITCH_HAND,
        script,
        link: Link::rtt(0.0),
        mode: ModePolicy::Direct,
    };
    [device(driver), device(grasper)]
}

/// What a rehearsal saw at its last tick.
#[derive(Debug, Clone, Default)]
struct Seen {
    /// The needle's pose, world.
    world_from_needle: Option<Isometry3<f32>>,
    /// Who held it.
    holder: Option<NeedleHolder>,
    /// Holes on the needle and on the thread.
    holes: (usize, usize),
    /// The thread's node `TAKE_PAST_LAST_HOLE_MM` past its last hole, world, mm.
    free_end_mm: Option<Vector3<f32>>,
}

/// The network the stitch runs over: both hands on the same link and mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StitchLink {
    /// The emulated path between each device and the server.
    pub link: Link,
    /// Direct, moderated or auto.
    pub mode: ModePolicy,
}

impl StitchLink {
    /// A LAN-like link with direct rendering (`sinew demo`'s).
    pub fn local() -> Self {
        Self {
            link: Link::rtt(0.0),
            mode: ModePolicy::Direct,
        }
    }

    /// Both hands of a stitch on this link.
    pub fn devices(
        &self,
        driver: (String, HandScript),
        grasper: (String, HandScript),
    ) -> [DrillDevice; 2] {
        stitch_devices(driver, grasper).map(|mut d| {
            d.link = self.link;
            d.mode = self.mode;
            d
        })
    }
}

/// Run the plan so far (`driver`, `grasper`) on virtual time over `link`, until the server has had the
/// plan's last pose and a round trip more to settle (the hands see what they did a round trip late, as a
/// surgeon at a distance does); what it left.
fn rehearse(
    world: &World,
    ids: (&str, &str),
    (driver, grasper): (&HandKeys, &HandKeys),
    driver_tool: usize,
    link: &StitchLink,
) -> anyhow::Result<Seen> {
    let end_s = driver.end_s().max(grasper.end_s()) + 1.5e-3 * link.link.rtt_ms;
    let mut seen = Seen::default();
    run_drill_observed(
        world,
        &link.devices(
            (ids.0.to_owned(), HandScript::Path(Arc::new(driver.path()?))),
            (
                ids.1.to_owned(),
                HandScript::Path(Arc::new(grasper.path()?)),
            ),
        ),
        end_s,
        |server: &ServerTick, _| {
            let Some(tool) = server.sim().tools.get(driver_tool) else {
                return;
            };
            let (Some(needle), Some(hold), Some(thread)) =
                (tool.needle(), tool.needle_hold(), tool.thread())
            else {
                return;
            };
            seen.world_from_needle = Some(*hold.world_from_needle());
            seen.holder = Some(*hold.holder());
            seen.holes = (needle.holes().len(), thread.holes().len());
            let last_u = thread
                .holes()
                .iter()
                .map(|h| h.u_mm)
                .fold(f32::NEG_INFINITY, f32::max);
            seen.free_end_mm = thread
                .chain()
                .node_u_mm()
                .iter()
                .position(|&u| u >= last_u + TAKE_PAST_LAST_HOLE_MM)
                .and_then(|node| thread.nodes_mm().get(node).copied());
        },
    )?;
    Ok(seen)
}

/// Plan `world`'s stitch on a LAN-like link ([`StitchLink::local`]); see [`stitch_scripts_over`].
pub fn stitch_scripts(world: &World) -> anyhow::Result<StitchScripts> {
    stitch_scripts_over(world, &StitchLink::local())
}

/// Plan `world`'s stitch for hands on `link`, rehearsing each stage over that link before planning the next:
/// the next stage reaches for where the last one left things under this delay, as a surgeon at a distance
/// reaches for what the screen shows once it has settled. Fails when the world has no needle driver or
/// grasper, or a rehearsal did not leave what the next stage needs (a needle let go through both edges; a
/// needle drawn out with the thread through all four holes).
pub fn stitch_scripts_over(world: &World, link: &StitchLink) -> anyhow::Result<StitchScripts> {
    let device_of = |pick: fn(&InstrumentSpec) -> bool| {
        world
            .tools
            .iter()
            .position(|t| pick(&t.instrument))
            .map(|t| (t, world.tools[t].device_id.clone()))
    };
    let (driver_tool, driver_id) =
        device_of(|i| matches!(i, InstrumentSpec::NeedleDriver(_))).context("no needle driver")?;
    let (grasper_tool, grasper_id) =
        device_of(|i| matches!(i, InstrumentSpec::Grasper(_))).context("no grasper")?;
    let InstrumentSpec::NeedleDriver(spec) = world.tools[driver_tool].instrument else {
        anyhow::bail!("tool {driver_tool} is not a needle driver");
    };
    let ids = (driver_id.as_str(), grasper_id.as_str());
    let pass = pass_path(world, &stitch_site(world)?)?;
    let mut driver = pass.driver.clone();
    let park = Isometry3::from_parts(
        Vector3::from(GRASPER_PARK_MM).into(),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f32::consts::FRAC_PI_2),
    );
    let mut grasper = HandKeys::new(
        Vector3::from(world.tools[grasper_tool].device_origin_in_world_mm),
        &park,
        0,
    );
    // Stage 1: the pass and the driver letting go, the grasper parked.
    let aside_s = release(&mut driver, pass.done_s);
    grasper.hold(aside_s, 0);
    let seen = rehearse(world, ids, (&driver, &grasper), driver_tool, link)
        .context("rehearsing the pass")?;
    anyhow::ensure!(
        seen.holder == Some(NeedleHolder::Loose)
            && seen.holes.0 + seen.holes.1 == 4
            && seen.holes.0 > 0,
        "the rehearsed pass let the needle go held by {:?} with {} holes on it and {} on the thread: not through \
         both edges and loose",
        seen.holder,
        seen.holes.0,
        seen.holes.1
    );
    let world_from_needle = seen.world_from_needle.context("no needle seen")?;
    let tip = world_from_needle * Point3::from(spec.arc.tip().point_mm);
    // Stage 2: the grasper takes the tip and draws the needle out along its curve.
    let times = regrasp_and_draw(&mut grasper, aside_s, &world_from_needle, &spec.arc);
    driver.hold(times.drawn_s, crate::stitch_hand_off_plan::DRIVER_OPEN);
    let seen = rehearse(world, ids, (&driver, &grasper), driver_tool, link)
        .context("rehearsing the hand-off")?;
    anyhow::ensure!(
        seen.holder.is_some_and(
            |h| matches!(h, NeedleHolder::Tool { tool, .. } if usize::from(tool) == grasper_tool)
        ) && seen.holes == (0, 4),
        "after the rehearsed hand-off the needle is held by {:?} with {} holes on it and {} on the thread: not \
         drawn out by the grasper",
        seen.holder,
        seen.holes.0,
        seen.holes.1
    );
    let free_end = seen
        .free_end_mm
        .context("the thread is too short to take past its last hole")?;
    let tail =
        seen.world_from_needle.context("no needle seen")? * Point3::from(spec.arc.tail().point_mm);
    // Stage 3: the driver takes the free end; both draw the stitch crossed and hold.
    let taken_s = take_free_end(&mut driver, times.drawn_s, &free_end);
    let end_s = tighten(
        &mut driver,
        &mut grasper,
        taken_s,
        &tail.coords,
        pass.exit_side,
        &DrawPlan::wound(),
    );
    Ok(StitchScripts {
        driver: (driver_id, HandScript::Path(Arc::new(driver.path()?))),
        grasper: (grasper_id, HandScript::Path(Arc::new(grasper.path()?))),
        end_s,
        tip_mm: [tip.x, tip.y, tip.z],
        free_end_mm: [free_end.x, free_end.y, free_end.z],
    })
}

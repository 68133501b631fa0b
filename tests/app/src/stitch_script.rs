//! The scripted stitch as the simulated surgeons' scripts: [`crate::stitch_plan`]'s paths, after a rehearsal
//! of the pass on virtual time through the real server tick and device loops ([`crate::drill`]) has found
//! where the thread lies for the grasper to take it (15 mm past its entry), as a surgeon looks before
//! reaching. `sinew demo` runs it for a world with a needle driver and a grasper; the scripted-stitch test
//! checks the whole stitch the same way.
//!
//! Owns: [`StitchScripts`], [`stitch_scripts`], [`stitch_site`] (where a world's stitch goes) and
//! [`stitch_devices`] (the hands that run it). Must not: open sessions (the rehearsal is on virtual time).

use std::sync::Arc;

use anyhow::Context as _;
use hapticserver::{HandPreset, HandScript, ModePolicy};
use sinew_server::server_tick::ServerTick;
use sinew_server::world::{InstrumentSpec, World};

use crate::drill::{DrillDevice, Link, run_drill_observed};
use crate::stitch_plan::{DrawPlan, StitchSite, pass_path, stitch_paths};

/// The hands a stitch is planned for: firm (a surgeon pushing a needle in grips the driver firmly; the plan's
/// push is sized for it).
pub const STITCH_HAND: HandPreset = HandPreset::Firm;

/// The grasper takes the thread this far past its entry hole, mm.
const GRASP_PAST_ENTRY_MM: f32 = 15.0;

/// Both surgeons' scripts for one stitch.
#[derive(Debug, Clone)]
pub struct StitchScripts {
    /// The needle driver's device and script.
    pub driver: (String, HandScript),
    /// The grasper's device and script.
    pub grasper: (String, HandScript),
    /// When the stitch is drawn tight and held to its end, s of script time.
    pub end_s: f64,
    /// Where the rehearsal found the thread for the grasper, world, mm.
    pub grasp_mm: [f32; 3],
}

/// Where `world`'s stitch goes: the needle's centre 3 mm above the middle of its objects' top (the wound of
/// `worlds/suture_wound.toml` lies there, between its two blocks).
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

/// Plan `world`'s stitch and rehearse its pass. Fails when the world has no needle driver or grasper, or the
/// rehearsed pass did not leave the thread in the tissue (the grasper would have nothing to take).
pub fn stitch_scripts(world: &World) -> anyhow::Result<StitchScripts> {
    let device_of = |pick: fn(&InstrumentSpec) -> bool| {
        world
            .tools
            .iter()
            .position(|t| pick(&t.instrument))
            .map(|t| (t, world.tools[t].device_id.clone()))
    };
    let (driver_tool, driver_id) =
        device_of(|i| matches!(i, InstrumentSpec::NeedleDriver(_))).context("no needle driver")?;
    let (_, grasper_id) =
        device_of(|i| matches!(i, InstrumentSpec::Grasper(_))).context("no grasper")?;
    let pass = pass_path(world, &stitch_site(world)?)?;
    // The rehearsal: the pass alone, the grasper parked; then where the thread lies past its entry.
    let (driver, parked, _) = stitch_paths(world, &pass, &DrawPlan::wound([0.0; 3]))?;
    let mut found: Option<[f32; 3]> = None;
    let mut holes = 0;
    run_drill_observed(
        world,
        &stitch_devices(
            (driver_id.clone(), HandScript::Path(Arc::new(driver))),
            (grasper_id.clone(), HandScript::Path(Arc::new(parked))),
        ),
        pass.done_s,
        |server: &ServerTick, _| {
            let Some(thread) = server.sim().tools.get(driver_tool).and_then(|t| t.thread()) else {
                return;
            };
            holes = thread.holes().len();
            found = thread.holes().first().and_then(|entry| {
                let node = thread
                    .chain()
                    .node_u_mm()
                    .iter()
                    .position(|&u| u >= entry.u_mm + GRASP_PAST_ENTRY_MM)?;
                let p = thread.nodes_mm().get(node)?;
                Some([p.x, p.y, p.z])
            });
        },
    )
    .context("rehearsing the pass")?;
    let grasp_mm = found.with_context(|| {
        format!(
            "the rehearsed pass left the thread in {holes} holes: no thread past an entry to take"
        )
    })?;
    let (driver, grasper, end_s) = stitch_paths(world, &pass, &DrawPlan::wound(grasp_mm))?;
    Ok(StitchScripts {
        driver: (driver_id, HandScript::Path(Arc::new(driver))),
        grasper: (grasper_id, HandScript::Path(Arc::new(grasper))),
        end_s,
        grasp_mm,
    })
}

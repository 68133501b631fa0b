//! A suture thread reaches the viewers over real zenoh sessions on loopback (`worlds/suture_block.toml`): the needle
//! driver's device holds it above the skin, the server lays out and steps its thread, and every viewer (one
//! watching from the start, one joining late, through the snapshot) holds its polyline: 65 nodes (64
//! segments), the first at the needle's tail, the rest hanging from it; and where the needle lies (protocol 15's
//! `needles`: in its driver's jaws as loaded, the driver's own pose).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::time::Duration;

use hapticserver::HandScript;
use sinew_protocol::{
    InstrumentInfo, NeedleState, ThreadState, ToolInfo, ToolState, needle_point_in_tool_mm,
};
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, serial, start_server, start_sim_device,
    start_viewer, wait_until,
};
use sinew_viewer::ViewerHandle;

/// The needle's tail in the world for a needle that lies at `state` (its driver's jaws' pose as loaded), mm.
fn tail_mm(info: &ToolInfo, state: &NeedleState) -> [f32; 3] {
    let InstrumentInfo::NeedleDriver {
        needle_radius_mm,
        grasp_at_rad,
        ..
    } = info.instrument
    else {
        panic!("tool {} is not a needle driver: {info:?}", info.tool);
    };
    let [qx, qy, qz, w] = state.orientation_xyzw;
    let v = needle_point_in_tool_mm(needle_radius_mm, grasp_at_rad, 0.0);
    // v + 2w (q x v) + 2 q x (q x v), q the quaternion's vector part.
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let q = [qx, qy, qz];
    let t = cross(q, v);
    let u = cross(q, t);
    std::array::from_fn(|i| state.position_mm[i] + v[i] + 2.0 * w * t[i] + 2.0 * u[i])
}

/// What a viewer's thread and needle say.
#[derive(Debug)]
struct Seen {
    tool: u16,
    nodes: Vec<[f32; 3]>,
    /// The needle's tail, world, mm.
    tail: [f32; 3],
    /// How far the needle lies from its driver's pose, mm (a quaternion dot product off 1 counts 1000 mm per
    /// unit).
    needle_off: f32,
}

/// What the viewer's thread and needle say, once it has a thread.
fn thread_seen(viewer: &ViewerHandle) -> Option<Seen> {
    viewer.with_replica(|r| {
        let thread: &ThreadState = r.tool_states().threads.first()?;
        let info = r.tools().iter().find(|t| t.tool == thread.tool)?;
        let state: &ToolState = r
            .tool_states()
            .tools
            .iter()
            .find(|t| t.tool == thread.tool)?;
        let needle = r
            .tool_states()
            .needles
            .iter()
            .find(|n| n.tool == thread.tool)?;
        let turned: f32 = (0..4)
            .map(|i| needle.orientation_xyzw[i] * state.orientation_xyzw[i])
            .sum::<f32>()
            .abs();
        Some(Seen {
            tool: thread.tool,
            nodes: thread.nodes_mm().collect(),
            tail: tail_mm(info, needle),
            needle_off: distance_mm(needle.position_mm, state.position_mm)
                + (1.0 - turned).abs() * 1000.0,
        })
    })
}

fn distance_mm(a: [f32; 3], b: [f32; 3]) -> f32 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt()
}

#[test]
fn a_needle_drivers_thread_reaches_every_viewer_and_a_late_joiner() {
    let _serial = serial();
    let world = load_shipped_world("suture_block.toml").unwrap();
    let endpoint = free_loopback_endpoint().unwrap();
    let server = start_server(world, &endpoint, Pacing::Sleep).unwrap();
    let viewer = start_viewer("suture-block", "instructor", &endpoint).unwrap();
    assert!(viewer.wait_for_snapshot(Duration::from_secs(5)));
    assert!(
        viewer.with_replica(|r| r.tool_states().threads.is_empty()),
        "a thread before any device drives the needle driver"
    );
    // The driver 20 mm above the skin (device frame; its origin is at x = -10 mm).
    let _left = start_sim_device(
        "suture-block",
        "left",
        HandScript::Hold {
            position_mm: [0.0, 0.0, 20.0],
        },
        &endpoint,
        Pacing::Sleep,
    )
    .unwrap();
    // Laid out from the tail, then it falls: wait until its free end hangs 10 mm below the tail.
    let hanging = |viewer: &ViewerHandle| {
        thread_seen(viewer).is_some_and(|Seen { nodes, tail, .. }| {
            nodes.last().is_some_and(|end| end[2] < tail[2] - 10.0)
        })
    };
    assert!(
        wait_until(Duration::from_secs(15), || hanging(&viewer)),
        "the viewer never saw the thread hang: {:?}",
        thread_seen(&viewer)
    );
    for watcher in [
        viewer,
        start_viewer("suture-block", "late", &endpoint).unwrap(),
    ] {
        assert!(watcher.wait_for_snapshot(Duration::from_secs(5)));
        assert!(
            wait_until(Duration::from_secs(5), || hanging(&watcher)),
            "{:?}",
            thread_seen(&watcher)
        );
        let Seen {
            tool,
            nodes,
            tail,
            needle_off,
        } = thread_seen(&watcher).unwrap();
        assert_eq!(tool, 0, "the needle driver is tool 0");
        // In its driver's jaws as loaded, the needle lies at the driver's own pose.
        assert!(
            needle_off < 0.01,
            "the needle lies {needle_off} off its driver"
        );
        assert_eq!(nodes.len(), 65, "64 segments");
        // The needle moves with the thread of the same frame: the first node sits on its tail.
        let off = distance_mm(nodes[0], tail);
        assert!(
            off < 0.5,
            "the thread starts {off} mm from the needle's tail"
        );
        // No jump along it: neighbours a segment apart (150 mm in 64, stretched a little at most).
        let longest = nodes
            .windows(2)
            .map(|p| distance_mm(p[0], p[1]))
            .fold(0.0, f32::max);
        assert!(longest < 3.0, "a segment {longest} mm long");
    }
    assert_eq!(server.stats().sim_faults, 0);
}

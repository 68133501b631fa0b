//! Probing the shipped pad on virtual time: the force points along the pad's outward normal (+z), grows
//! with depth, stays finite and bounded, and the tissue relaxes when the tool is released.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

fn pad() -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    Sim::new(&load_world(&path).expect("pad world loads")).expect("pad builds")
}

/// Force range (lo, hi) of tool 0 over 3 s under a still device (+-1 um of hand jitter) after settling `depth`.
fn still_tool_force_range(mut sim: Sim, depth: f32, jitter: &mut u32) -> (f32, f32) {
    let mut commands = [press(-2.0), press(-2.0)];
    settle(&mut sim, &mut commands, 0, depth, 0.3, 1.0);
    let mut out = [ToolOutput::default(); 2];
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let rest = commands[0].position_device_mm;
    for _ in 0..3000 {
        *jitter ^= *jitter << 13;
        *jitter ^= *jitter >> 17;
        *jitter ^= *jitter << 5;
        let dz = (*jitter % 2001) as f32 * 1e-6 - 1e-3;
        commands[0].position_device_mm = [rest[0], rest[1], rest[2] + dz];
        sim.step(0.001, &commands, &mut out);
        lo = lo.min(out[0].force_world_n.z);
        hi = hi.max(out[0].force_world_n.z);
    }
    (lo, hi)
}

fn press(depth_mm: f32) -> ToolCommand {
    press_at(0.0, depth_mm)
}

/// Press at device x (the left device's origin is world x = -18, the right one's +18).
fn press_at(x_mm: f32, depth_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        // Sphere radius 4: centre at 4 - depth puts its bottom `depth` below the rest surface.
        position_device_mm: [x_mm, 0.0, 4.0 - depth_mm],
        velocity_device_mm_s: [0.0; 3],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    }
}

/// Lower the tool to `depth` over `ramp_s`, hold for `hold_s`, return the last output.
fn settle(
    sim: &mut Sim,
    commands: &mut [ToolCommand; 2],
    tool: usize,
    depth_mm: f32,
    ramp_s: f32,
    hold_s: f32,
) -> ToolOutput {
    let dt = 0.001;
    let mut out = [ToolOutput::default(); 2];
    let start = 4.0 - commands[tool].position_device_mm[2];
    let ticks = (ramp_s / dt) as usize;
    for k in 0..ticks {
        let d = start + (depth_mm - start) * (k + 1) as f32 / ticks as f32;
        commands[tool] = press_at(commands[tool].position_device_mm[0], d);
        sim.step(dt, commands, &mut out);
    }
    for _ in 0..(hold_s / dt) as usize {
        let report = sim.step(dt, commands, &mut out);
        assert_eq!(report.faults, 0);
    }
    out[tool]
}

#[test]
fn probe_force_points_out_of_the_pad_and_grows_with_depth() {
    let mut sim = pad();
    let mut commands = [press(-2.0), press(-2.0)];
    let mut last = 0.0;
    for depth in [2.0, 4.0, 6.0] {
        let out = settle(&mut sim, &mut commands, 0, depth, 0.3, 0.3);
        let f = out.force_world_n;
        println!(
            "depth {depth} mm: force {f:?} ({} held nodes)",
            out.held_nodes
        );
        assert!(out.in_contact);
        assert!(
            f.z > 0.0 && f.z > 0.95 * f.norm(),
            "force {f:?} not along +z"
        );
        assert!(
            f.z > last * 1.2,
            "force did not grow with depth: {} then {}",
            last,
            f.z
        );
        assert!(f.norm() <= 3.3 + 1e-4);
        last = f.z;
    }
    assert!(last > 0.3, "6 mm deep gives only {last} N");
}

#[test]
fn a_tool_out_of_contact_feels_nothing() {
    let mut sim = pad();
    let mut commands = [press(-2.0), press(-2.0)];
    let left = settle(&mut sim, &mut commands, 0, 5.0, 0.2, 0.2);
    commands[1] = press(-16.0);
    let mut out = [ToolOutput::default(); 2];
    sim.step(0.001, &commands, &mut out);
    assert!(left.in_contact);
    assert_eq!(out[1].force_world_n.norm(), 0.0);
    assert!(!out[1].in_contact);
}

#[test]
fn two_tools_pressing_deform_the_tissue_between_them_with_bounded_forces() {
    let mut sim = pad();
    // Tools 12 mm apart (world x = -6 and +6): 4 mm of tissue between the spheres.
    let mut commands = [press_at(12.0, -2.0), press_at(-12.0, -2.0)];
    settle(&mut sim, &mut commands, 0, 6.0, 0.3, 0.1);
    let right = settle(&mut sim, &mut commands, 1, 6.0, 0.3, 0.3);
    let mut out = [ToolOutput::default(); 2];
    sim.step(0.001, &commands, &mut out);
    // The node midway between the tools (world x = 0) sags below the rest plane.
    let pad = &sim.objects[0];
    let mid = pad
        .model
        .rest_positions_mm()
        .iter()
        .position(|p| p.x.abs() < 0.01 && p.y.abs() < 0.01)
        .unwrap();
    assert!(
        pad.state.positions_mm[mid].z < -0.05,
        "midpoint z {}",
        pad.state.positions_mm[mid].z
    );
    for o in out.iter().chain([&right]) {
        assert!(o.force_world_n.iter().all(|c| c.is_finite()));
        assert!(o.force_world_n.norm() <= 3.3 + 1e-4);
        assert!(o.force_world_n.z > 0.0);
    }
}

#[test]
fn released_tissue_relaxes_to_rest() {
    let mut sim = pad();
    let mut commands = [press(-2.0), press(-2.0)];
    settle(&mut sim, &mut commands, 0, 6.0, 0.2, 0.2);
    let deepest = |sim: &Sim| {
        sim.objects[0]
            .state
            .positions_mm
            .iter()
            .map(|p| -p.z)
            .fold(0.0f32, f32::max)
    };
    assert!(deepest(&sim) > 4.0);
    commands[0].active = false;
    let mut out = [ToolOutput::default(); 2];
    for _ in 0..1000 {
        sim.step(0.001, &commands, &mut out);
    }
    assert_eq!(out[0].force_world_n.norm(), 0.0);
    assert!(
        deepest(&sim) < 0.05,
        "still {} mm deep after 1 s",
        deepest(&sim)
    );
}

#[test]
fn non_finite_tool_pose_releases_the_tool_instead_of_corrupting_the_tissue() {
    let mut sim = pad();
    let mut commands = [press(-2.0), press(-2.0)];
    settle(&mut sim, &mut commands, 0, 4.0, 0.1, 0.1);
    commands[0].position_device_mm[2] = f32::NAN;
    let mut out = [ToolOutput::default(); 2];
    let report = sim.step(0.001, &commands, &mut out);
    assert_eq!(report.faults, 0);
    assert_eq!(out[0].force_world_n.norm(), 0.0);
    assert!(sim.objects[0].state.is_finite());
}

/// Regression: held nodes kept their tangential velocity, crept round the frictionless probe, dropped out of
/// contact and snapped back: a ~40 mN, ~2 Hz force ripple under a perfectly still tool (seen with the stylus
/// centre resting 2.166 mm below the surface, i.e. 6.166 mm deep, with the micrometre jitter a held stylus has).
#[test]
fn held_probe_force_has_no_ripple_under_a_still_tool() {
    let mut jitter = 0x9E37_79B9u32;
    // Past 1.5 probe radii the dent's walls close in above the probe's equator. Until side-entering nodes left
    // radially, they were pushed along the tissue normal through the whole probe, sprang back and re-entered: a
    // 5-tick, ~3% (30 mN of 1.1 N) chatter from about 5.8 mm deep, with a rigid or a coupled tool alike.
    for depth in [2.0, 4.0, 5.0, 5.9, 6.166, 7.0] {
        let (lo, hi) = still_tool_force_range(pad(), depth, &mut jitter);
        assert!(lo > 0.05, "force {lo} at depth {depth}");
        // Imperceptible: under 2% of the force (the just-noticeable difference for force is about 7%).
        // Before the fix this configuration rippled 2.9% (33 mN of 1.14 N).
        assert!(
            hi - lo < 0.02 * hi,
            "force ripples {:.4} N under a still tool {depth} mm deep ({lo:.4}..{hi:.4})",
            hi - lo
        );
    }
}

/// Regression: a pad settling after a poke decayed its velocities and z coordinates into subnormal floats,
/// which x86 computes ~100x slower (the spring kernel went from ~6 to ~20 ns per spring).
#[test]
fn a_settling_tissue_never_holds_subnormal_floats() {
    let mut sim = pad();
    let mut commands = [press(-2.0), press(-2.0)];
    settle(&mut sim, &mut commands, 0, 3.0, 0.1, 0.1);
    commands[0].active = false;
    let mut out = [ToolOutput::default(); 2];
    for _ in 0..3000 {
        sim.step(0.001, &commands, &mut out);
    }
    let state = &sim.objects[0].state;
    let subnormal = state
        .positions_mm
        .iter()
        .chain(&state.velocities_mm_s)
        .flat_map(|v| v.iter())
        .filter(|c| c.is_subnormal())
        .count();
    assert_eq!(
        subnormal, 0,
        "{subnormal} subnormal components after settling"
    );
}

/// A closed 6 mm cube, centred on the tool origin, faces counter-clockwise from outside.
const CUBE_OBJ: &str = "v -3 -3 -3\nv 3 -3 -3\nv 3 3 -3\nv -3 3 -3\nv -3 -3 3\nv 3 -3 3\nv 3 3 3\nv -3 3 3\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 8 7\nf 4 7 3\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n";

/// `obj` written as `tool.obj` in a fresh directory; its path.
fn write_tool_obj(obj: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "sinew-mesh-tool-{}-{}",
        std::process::id(),
        obj.len()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let tool_path = dir.join("tool.obj");
    std::fs::write(&tool_path, obj).unwrap();
    tool_path
}

/// The shipped pad with the left probe replaced by a mesh tool (`obj`, in mm, loaded and checked closed as the
/// world loader does a tool's `shape = { kind = "mesh", ... }`).
fn pad_with_mesh_tool(obj: &str) -> sinew_server::world::World {
    use sinew_server::world::{ToolShapeSpec, load_obj_mesh, validate_closed};
    let mut world =
        load_world(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml"))
            .unwrap();
    let mesh = load_obj_mesh(&write_tool_obj(obj), 1.0).unwrap();
    validate_closed(&mesh).unwrap();
    world.tools[0].shape = ToolShapeSpec::Mesh(mesh);
    world
}

/// The shipped pad's text with the left probe's shape a mesh tool (`obj`, written to its own file), and
/// what the world loader makes of it. Text, not a scene edit: the loader's refusal of the mesh is under test.
fn pad_file_with_mesh_tool(
    obj: &str,
) -> Result<sinew_server::world::World, sinew_server::world::WorldError> {
    let worlds = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds");
    let tool_path = write_tool_obj(obj);
    let text = std::fs::read_to_string(worlds.join("pad.toml"))
        .unwrap()
        .replacen(
            r#"shape = { kind = "sphere", radius_mm = 4.0 }"#,
            &format!(
                r#"shape = {{ kind = "mesh", mesh = "{}", units = "mm" }}"#,
                tool_path.display()
            ),
            1,
        );
    sinew_server::world::parse_world(&worlds.join("pad.toml"), &text)
}

#[test]
fn a_mesh_tool_presses_the_pad_and_feels_it_push_back_along_the_normal() {
    let world = pad_with_mesh_tool(CUBE_OBJ);
    let mut sim = Sim::new(&world).unwrap();
    let mut out = [ToolOutput::default(); 2];
    let mut last = 0.0;
    for depth in [1.0f32, 2.5] {
        let mut command = press(0.0);
        for k in 0..600 {
            // Cube half-size 3: centre at 3 - depth puts its bottom face `depth` below the rest surface.
            let d = depth * ((k + 1) as f32 / 300.0).min(1.0);
            command.position_device_mm = [0.0, 0.0, 3.0 - d];
            sim.step(0.001, &[command, ToolCommand::default()], &mut out);
        }
        let f = out[0].force_world_n;
        assert!(
            out[0].in_contact && f.z > 0.95 * f.norm(),
            "force {f:?} at depth {depth}"
        );
        assert!(
            f.z > last * 1.5,
            "force did not grow with depth: {last} then {}",
            f.z
        );
        last = f.z;
        // The flat face flattens the dent: the node under the centre sits on the face.
        let centre = sim.objects[0]
            .model
            .rest_positions_mm()
            .iter()
            .position(|p| (p.x + 18.0).abs() < 0.01 && p.y.abs() < 0.01)
            .unwrap();
        // The face is where the coupled tool is (F / k_c short of the commanded pose), 3 mm below its centre.
        let face_z = sim.tools[0].position_mm.z - 3.0;
        assert!(
            (sim.objects[0].state.positions_mm[centre].z - face_z).abs() < 0.05,
            "centre node at {} mm, face at {face_z} mm",
            sim.objects[0].state.positions_mm[centre].z
        );
    }
}

#[test]
fn an_open_tool_mesh_is_refused() {
    let open: String = CUBE_OBJ
        .lines()
        .filter(|l| *l != "f 5 7 8")
        .map(|l| format!("{l}\n"))
        .collect();
    let error = pad_file_with_mesh_tool(&open).unwrap_err().to_string();
    assert!(
        error.contains("not closed") && error.contains("tools[0].shape.mesh"),
        "{error}"
    );
}

/// A diverging tissue (here forced past the loader's stability check: 200x the stable step, so even the
/// anti-divergence guard's smallest step, 1/16, cannot save it) is reset and counted as a fault; no tool ever
/// sees a non-finite or over-limit force.
#[test]
fn a_diverging_tissue_is_contained_and_never_reaches_a_tool() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut world = load_world(&path).unwrap();
    world.objects[0].material.stiffness_n_per_mm *= 40_000.0; // stable bound drops ~200x below dt
    let mut sim = Sim::new(&world).unwrap();
    let mut out = [ToolOutput::default(); 2];
    let mut faults = 0;
    for k in 0..2000 {
        let depth = (k as f32 / 200.0).min(1.0) * 4.0;
        let report = sim.step(0.001, &[press(depth), press(-2.0)], &mut out);
        faults += report.faults;
        for o in &out {
            assert!(
                o.force_world_n.iter().all(|c| c.is_finite()),
                "non-finite force at tick {k}"
            );
            assert!(o.force_world_n.norm() <= 3.3 + 1e-4);
        }
        assert!(sim.objects[0].state.is_finite());
    }
    assert!(
        faults > 0,
        "the overstiff tissue never diverged: the test proves nothing"
    );
}

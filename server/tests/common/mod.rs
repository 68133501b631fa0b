//! Fixtures shared by the server's integration tests and benches (the largest-tissue bench includes this file
//! with `#[path]`): scratch directories, and a world around a flat sheet with the pad's material. World files
//! as text are built in [`world_toml`]; scenes changed in code (a loaded world's typed fields) in
//! [`scene_edits`].
#![allow(dead_code)] // each test binary uses its own subset
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

pub mod mesh_pieces;
pub mod scene_edits;
pub mod world_toml;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::{grid_sheet, to_obj_text};
use world_toml::{SheetWorldToml, fixed_plane, sphere_tool};

/// A fresh directory under the system temp dir, unique per process and call.
pub fn scratch_dir(prefix: &str) -> PathBuf {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "{prefix}-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A world around an `nx` x `ny` sheet of 1 mm cells (`sheet.obj`, written by [`write_sheet_world`]) with
/// worlds/pad.toml's material per cell (mass scaled by area: every node has the pad's mass), its rim fixed, and
/// one 4 mm sphere probe (device `probe`) over the centre. `extra` is spliced into the object table.
pub fn sheet_world_text(nx: usize, ny: usize, integrator: &str, dt_s: f32, extra: &str) -> String {
    sheet_world_toml(nx, ny, integrator, dt_s, extra).text()
}

/// [`sheet_world_text`]'s world, its parts still apart (to add a `[sim]` section, say).
pub fn sheet_world_toml(
    nx: usize,
    ny: usize,
    integrator: &str,
    dt_s: f32,
    extra: &str,
) -> SheetWorldToml {
    let mass_kg = 0.6 * (nx * ny) as f32 / (80.0 * 60.0);
    let (hx, hy) = (nx as f32 / 2.0, ny as f32 / 2.0);
    SheetWorldToml {
        scene: "sheet".into(),
        sim: String::new(),
        name: "sheet".into(),
        mesh: "sheet.obj".into(),
        integrator: integrator.into(),
        dt_s: dt_s.to_string(),
        object_keys: format!("{extra}\n"),
        material: format!(
            "mass_kg = {mass_kg}\nstiffness_n_per_mm = 0.015\ndamping_n_s_per_mm = 0.000003\n\
             anchor_stiffness_n_per_mm = 0.008\ndrag_per_s = 150.0\n"
        ),
        fixed: [
            ([-hx, 0.0, 0.0], [-1.0, 0.0, 0.0]),
            ([hx, 0.0, 0.0], [1.0, 0.0, 0.0]),
            ([0.0, -hy, 0.0], [0.0, -1.0, 0.0]),
            ([0.0, hy, 0.0], [0.0, 1.0, 0.0]),
        ]
        .into_iter()
        .map(|(point, normal)| fixed_plane(point, normal, 0.01))
        .collect(),
        tool: sphere_tool("probe", "probe", 4.0) + "max_force_n = 3.3\n",
    }
}

/// Write `text` as `world.toml` beside an `nx` x `ny` sheet of 1 mm cells in a fresh directory; returns the
/// world path.
pub fn write_sheet_world(prefix: &str, text: &str, nx: usize, ny: usize) -> PathBuf {
    let dir = scratch_dir(prefix);
    std::fs::write(
        dir.join("sheet.obj"),
        to_obj_text(&grid_sheet(nx, ny, 1.0), &[]),
    )
    .unwrap();
    let path = dir.join("world.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A server tick over `world` at its tick rate, with the default deadband.
pub fn server_tick(world: &sinew_server::world::World) -> sinew_server::server_tick::ServerTick {
    sinew_server::server_tick::ServerTick::new(
        sinew_server::sim::Sim::new(world).expect("the world builds"),
        (1.0 / world.tick_hz) as f32,
        world.pose_timeout_s,
        sinew_server::server_tick::DeadbandParams::default(),
    )
}

/// Show tick `k` of `tick` (its step's report `step`) to `observer`, its events and transitions dropped.
pub fn observe_tick(
    observer: &mut sinew_server::training::SessionObserver,
    tick: &sinew_server::server_tick::ServerTick,
    k: u64,
    step: &sinew_server::sim::StepReport,
) {
    let view = sinew_server::training::TickView {
        tick: k,
        active: tick.tools_active(),
        outputs: tick.outputs(),
        step,
    };
    observer.observe(&view, |_| {}, |_, _| {});
}

/// A fresh, usable pose number `seq` at `position_device_mm`, upright.
pub fn pose_at(
    seq: u64,
    position_device_mm: [f32; 3],
) -> Option<sinew_server::server_tick::PoseInput> {
    Some(sinew_server::server_tick::PoseInput {
        pose: sinew_protocol::DevicePose {
            seq,
            position_mm: position_device_mm,
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..sinew_protocol::DevicePose::default()
        },
        age_s: 0.0,
        usable: true,
    })
}

/// A finite-element model of `mesh`: lumped masses from `density_kg_per_m3` by tetrahedron volume share, springs
/// along the tetrahedra's edges with no stiffness (the elements carry it), `fixed` nodes by rest position.
pub fn fem_model(
    mesh: &sinew_server::world::TetMesh,
    material: sinew_server::tissue::fem::FemMaterial,
    density_kg_per_m3: f32,
    fixed: impl Fn(sinew_server::tissue::Vec3) -> bool,
) -> sinew_server::tissue::MassSpringModel {
    use sinew_server::tissue::{MassSpringModel, ModelParts, Vec3};
    let x: Vec<Vec3> = mesh
        .surface
        .positions_mm
        .iter()
        .map(|p| Vec3::from(*p))
        .collect();
    let mut mass_kg = vec![0.0f32; x.len()];
    let mut edges = Vec::new();
    for tet in &mesh.tets {
        let volume_mm3 = sinew_server::tissue::volume::tet_volume_mm3(&x, *tet).abs();
        for &i in tet {
            mass_kg[i as usize] += volume_mm3 / 4.0 * density_kg_per_m3 * 1e-9;
        }
        for (p, q) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            edges.push([tet[p].min(tet[q]), tet[p].max(tet[q])]);
        }
    }
    edges.sort_unstable();
    edges.dedup();
    MassSpringModel::from_parts(ModelParts {
        fixed: x.iter().map(|p| fixed(*p)).collect(),
        rest_positions_mm: x,
        mass_kg,
        edge_stiffness_n_per_mm: vec![0.0; edges.len()],
        edge_damping_n_s_per_mm: vec![0.0; edges.len()],
        edges,
        triangles: mesh.surface.triangles.clone(),
        tets: mesh.tets.clone(),
        fem: Some(material),
        ..ModelParts::default()
    })
}

/// The same mesh as [`fem_model`], as springs calibrated from `youngs_n_per_mm2` and `poisson` (Lloyd et al.'s
/// fit plus the per-tetrahedron volume term for the rest of Poisson's ratio), as a world with
/// `youngs_modulus_kpa` builds it.
pub fn calibrated_spring_model(
    mesh: &sinew_server::world::TetMesh,
    youngs_n_per_mm2: f32,
    poisson: f32,
    density_kg_per_m3: f32,
    fixed: impl Fn(sinew_server::tissue::Vec3) -> bool,
) -> sinew_server::tissue::MassSpringModel {
    use sinew_server::tissue::calibration::{
        calibrated_edge_stiffness, volume_supplement_n_per_mm2,
    };
    use sinew_server::tissue::{MassSpringModel, Vec3};
    let material = sinew_server::tissue::fem::FemMaterial {
        youngs_modulus_n_per_mm2: youngs_n_per_mm2,
        poisson_ratio: poisson,
        corotated: true,
    };
    let mut parts = fem_model(mesh, material, density_kg_per_m3, fixed).to_parts();
    parts.fem = None;
    let x: Vec<Vec3> = parts.rest_positions_mm.clone();
    parts.edge_stiffness_n_per_mm = calibrated_edge_stiffness(
        &x,
        &parts.edges,
        &parts.tets,
        &parts.triangles,
        youngs_n_per_mm2,
        poisson,
        0.0,
    );
    parts.tet_bulk_modulus_n_per_mm2 = volume_supplement_n_per_mm2(youngs_n_per_mm2, poisson);
    MassSpringModel::from_parts(parts)
}

/// The repository's `worlds/` directory.
pub fn worlds() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds")
}

/// worlds/fem_block.toml's left probe (a 4 mm sphere, device origin at world x = -10) with its bottom
/// `depth_mm` below the block's top face.
pub fn fem_block_press(depth_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.0, 0.0, 4.0 - depth_mm],
        velocity_device_mm_s: [0.0; 3],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    }
}

/// Move fem_block's left probe from `from_mm` to `depth_mm` deep over `ticks` and hold it `hold` more; every
/// tick's output. Every tick stays finite and within the tool's limit, with neither a halving nor a reset.
pub fn fem_block_move(
    sim: &mut Sim,
    from_mm: f32,
    depth_mm: f32,
    ticks: usize,
    hold: usize,
) -> Vec<ToolOutput> {
    let mut out = [ToolOutput::default(); 2];
    let mut all = Vec::with_capacity(ticks + hold);
    for k in 0..ticks + hold {
        let s = ((k + 1) as f32 / ticks as f32).min(1.0);
        let d = from_mm + (depth_mm - from_mm) * s;
        let report = sim.step(
            0.001,
            &[fem_block_press(d), ToolCommand::default()],
            &mut out,
        );
        assert_eq!((report.faults, report.retries), (0, 0), "tick {k}");
        let f = out[0].force_world_n;
        assert!(f.iter().all(|c| c.is_finite()) && f.norm() <= 3.3 + 1e-4);
        all.push(out[0]);
    }
    all
}

/// An object's rest surface height at world (x, y): the highest rest node within 2.5 mm, mm.
pub fn rest_surface_z_mm(object: &sinew_server::sim::SimObject, x_mm: f32, y_mm: f32) -> f32 {
    object
        .model
        .rest_positions_mm()
        .iter()
        .filter(|p| (p.xy() - nalgebra::Vector2::new(x_mm, y_mm)).norm() < 2.5)
        .map(|p| p.z)
        .fold(f32::MIN, f32::max)
}

/// How far the node furthest from its rest position is from it, mm.
pub fn furthest_from_rest_mm(object: &sinew_server::sim::SimObject) -> f32 {
    object
        .state
        .positions_mm
        .iter()
        .zip(object.model.rest_positions_mm())
        .map(|(x, r)| (x - r).norm())
        .fold(0.0f32, f32::max)
}

/// Every coordinate of an object's node positions, as bits (two runs that agree to the bit agree here).
pub fn position_bits(object: &sinew_server::sim::SimObject) -> Vec<u32> {
    object
        .state
        .positions_mm
        .iter()
        .flat_map(|p| p.iter().map(|c| c.to_bits()))
        .collect()
}

/// A tetrahedron's shape quality at `x` ([`sinew_server::tissue::volume::tet_shape_quality`]: 1 regular, 0
/// flat, negative turned over).
pub fn quality(x: &[sinew_server::tissue::Vec3], tet: &[u32; 4]) -> f32 {
    sinew_server::tissue::volume::tet_shape_quality(x, *tet)
}

/// The least share of its rest quality any tetrahedron of `o` keeps now.
pub fn worst_kept_quality(o: &sinew_server::sim::SimObject) -> f32 {
    o.model
        .tets()
        .tets
        .iter()
        .map(|t| quality(&o.state.positions_mm, t) / quality(o.model.rest_positions_mm(), t))
        .fold(f32::INFINITY, f32::min)
}

/// Two runs of one script (inline and threaded, say) gave the same bits: every tool's force every tick
/// (`a[tick][tool]`) and the final positions of object 0 of `sim_a` and `sim_b`.
pub fn assert_same_bits<T: AsRef<[sinew_server::tissue::Vec3]>>(
    a: &[T],
    b: &[T],
    sim_a: &Sim,
    sim_b: &Sim,
) {
    assert_eq!(a.len(), b.len(), "the runs differ in length");
    for (k, (fa, fb)) in a.iter().zip(b).enumerate() {
        for (t, (fa, fb)) in fa.as_ref().iter().zip(fb.as_ref()).enumerate() {
            assert_eq!(
                fa.map(f32::to_bits),
                fb.map(f32::to_bits),
                "tick {k}, tool {t}: {fa:?} against {fb:?}"
            );
        }
    }
    assert_eq!(
        position_bits(&sim_a.objects[0]),
        position_bits(&sim_b.objects[0])
    );
}

/// A tool held at `position_device_mm` (device frame) with its jaws closed by button 1 (`closed`) or open.
pub fn jaws_at(position_device_mm: [f32; 3], closed: bool) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm,
        jaws: sinew_server::interaction::JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    }
}

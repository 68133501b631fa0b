//! Hertz contact (issue "Tissue from material data"): a rigid sphere of radius R pressed d into a block much
//! larger than the contact gives F = 4/3 E* sqrt(R) d^1.5, E* = E / (1 - nu^2). Shared by the validation test
//! (`tests/tests/hertz.rs`) and the force-depth figure (`benches/hertz_figure.rs`).
//!
//! The block is `worlds/meshes/hertz_block.msh` (120 x 120 x 60 mm, unstructured tetrahedra graded from 0.5 mm
//! under the sphere; its generator sits beside it), its sides and floor fixed, loaded through the world loader
//! with each [`Material`] as a world file would give it, and built by the server's own model builder.
//!
//! Contact is solved statically by an active set: the surface nodes under the sphere are held on it at their
//! rest x, y (contact without slip; at nu = 0.45 this differs from frictionless Hertz by well under 2%, Spence
//! 1975), a node the tissue pulls on is let go, a node that comes through the sphere is taken, until nothing
//! changes. The force is what the held nodes push back with. Each depth starts from the last one's solution.

use std::path::Path;

use anyhow::Context as _;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::{
    ImplicitEuler, Integrator, MassSpringModel, ModelParts, TissueState, Vec3,
};
use sinew_server::world::{World, parse_world};

/// Young's modulus of the block, kPa.
pub const YOUNGS_KPA: f32 = 10.0;
/// Poisson's ratio of the block.
pub const POISSON: f32 = 0.45;
/// The indenter's radius, mm.
pub const RADIUS_MM: f32 = 8.0;

/// How the block's material is given, as a world file would give it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Material {
    /// `model = "fem-corotational"` with Young's modulus and Poisson's ratio.
    Fem,
    /// A mass-spring object with Young's modulus and Poisson's ratio: calibrated springs.
    CalibratedSprings,
    /// The hand-tuned per-edge springs of `worlds/tet_block.toml` (0.02 N/mm per edge, 100 kPa per-tetrahedron
    /// volume term), as worlds were written before material data.
    HandTunedSprings,
}

impl Material {
    /// Every material, in the order the figure draws them.
    pub const ALL: [Material; 3] = [
        Material::Fem,
        Material::CalibratedSprings,
        Material::HandTunedSprings,
    ];

    /// A short label.
    pub fn label(self) -> &'static str {
        match self {
            Material::Fem => "corotational FEM",
            Material::CalibratedSprings => "calibrated springs",
            Material::HandTunedSprings => "hand-tuned springs",
        }
    }

    fn world_keys(self) -> String {
        match self {
            Material::Fem => format!(
                "model = \"fem-corotational\"\n[objects.material]\nyoungs_modulus_kpa = {YOUNGS_KPA}\n\
                 poisson_ratio = {POISSON}\ndensity_kg_per_m3 = 1060.0\n"
            ),
            Material::CalibratedSprings => format!(
                "[objects.material]\nyoungs_modulus_kpa = {YOUNGS_KPA}\npoisson_ratio = {POISSON}\n\
                 density_kg_per_m3 = 1060.0\n"
            ),
            Material::HandTunedSprings => "[objects.material]\nstiffness_n_per_mm = 0.02\n\
                 tet_bulk_modulus_kpa = 100.0\ndensity_kg_per_m3 = 1060.0\n"
                .to_owned(),
        }
    }
}

/// The block with `material`, loaded from a world text through the world loader (mesh, fixed walls, keys).
pub fn block_parts(material: Material) -> anyhow::Result<ModelParts> {
    let world = block_world(material, "dt_s = 0.001\n")?;
    let spec = world
        .objects
        .first()
        .context("the Hertz block has an object")?;
    Ok(MassSpringModel::build(spec, Vec3::zeros()).to_parts())
}

/// The Hertz block's world with `material` and `step` (the object's `dt_s` and any rate keys), its indenter
/// over the block's centre.
fn block_world(material: Material, step: &str) -> anyhow::Result<World> {
    let mut text = format!(
        "scene = \"hertz-block\"\n\
         [[objects]]\nname = \"block\"\nmesh = \"meshes/hertz_block.msh\"\nunits = \"mm\"\n\
         integrator = \"implicit-euler\"\n{step}"
    );
    text.push_str(&material.world_keys());
    for (point, normal) in [
        ([-60.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ([60.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
        ([0.0, -60.0, 0.0], [0.0, -1.0, 0.0]),
        ([0.0, 60.0, 0.0], [0.0, 1.0, 0.0]),
        ([0.0, 0.0, -60.0], [0.0, 0.0, -1.0]),
    ] {
        text.push_str(&format!(
            "[[objects.fixed]]\nkind = \"plane\"\npoint_mm = {point:?}\nnormal = {normal:?}\ntolerance_mm = 0.01\n"
        ));
    }
    text.push_str(&format!(
        "[[tools]]\nname = \"indenter\"\ndevice = \"right\"\nshape = {{ kind = \"sphere\", radius_mm = {RADIUS_MM} }}\n"
    ));
    let path = crate::harness::worlds_dir().join("hertz_block.toml");
    parse_world(Path::new(&path), &text).context("the Hertz block's world")
}

/// The force, N, the simulation itself renders to the indenter pressed to each of `depths_mm` (increasing)
/// and held still, with the block a multi-rate object stepping at `step_hz` (one step a period): the force
/// a hand feels at 1 kHz from the local model of the object's latest step, once the block has settled.
pub fn sim_press(material: Material, step_hz: u32, depths_mm: &[f32]) -> anyhow::Result<Vec<f32>> {
    let step = format!("dt_s = {}\nstep_hz = {step_hz}\n", 1.0 / f64::from(step_hz));
    let world = block_world(material, &step)?;
    let mut sim = Sim::new(&world)?;
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut out = [ToolOutput::default()];
    let mut forces = Vec::with_capacity(depths_mm.len());
    let mut from_mm = -2.0f32;
    for &depth in depths_mm {
        // 0.5 s down to the depth, 1.5 s held (the sphere's lowest point `depth` below the block's top).
        for k in 0..2000 {
            let d = from_mm + (depth - from_mm) * ((k + 1) as f32 / 500.0).min(1.0);
            let command = ToolCommand {
                active: true,
                position_device_mm: [0.0, 0.0, RADIUS_MM - d],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                ..ToolCommand::default()
            };
            let report = sim.step(dt_s, &[command], &mut out);
            anyhow::ensure!(report.faults == 0, "the block faulted at {depth} mm");
        }
        forces.push(out[0].force_world_n.z);
        from_mm = depth;
    }
    Ok(forces)
}

/// Hertz's force at `depth_mm`, N.
pub fn hertz_n(depth_mm: f32) -> f32 {
    let youngs_star = YOUNGS_KPA * 1e-3 / (1.0 - POISSON * POISSON);
    4.0 / 3.0 * youngs_star * RADIUS_MM.sqrt() * depth_mm.powf(1.5)
}

/// Height of the sphere's underside above `(x, y)` with its lowest point at `-depth_mm`.
fn sphere_z(x: f32, y: f32, depth_mm: f32) -> f32 {
    let r2 = x * x + y * y;
    -depth_mm + RADIUS_MM - (RADIUS_MM * RADIUS_MM - r2.min(RADIUS_MM * RADIUS_MM)).sqrt()
}

/// The force, N, with which the block `parts` pushes back on the sphere pressed to each of `depths_mm`
/// (increasing).
pub fn press(parts: &ModelParts, depths_mm: &[f32]) -> Vec<f32> {
    let rest = parts.rest_positions_mm.clone();
    let top: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i].z.abs() < 1e-4 && rest[i].x.hypot(rest[i].y) < RADIUS_MM * 0.9)
        .collect();
    let mut held = vec![false; rest.len()];
    let mut positions = rest.clone();
    let mut forces = Vec::with_capacity(depths_mm.len());
    let mut internal = vec![Vec3::zeros(); rest.len()];
    for &depth in depths_mm {
        // Start from Hertz's contact radius sqrt(R d).
        let radius = (RADIUS_MM * depth).sqrt();
        for &i in &top {
            held[i] |= rest[i].x.hypot(rest[i].y) < 0.9 * radius;
        }
        let mut force_n = 0.0;
        for _round in 0..8 {
            let mut with_held = parts.clone();
            for &i in &top {
                with_held.fixed[i] = held[i];
            }
            let model = MassSpringModel::from_parts(with_held);
            let mut state = TissueState::at_rest(&model);
            state.positions_mm.clone_from(&positions);
            for &i in &top {
                if held[i] {
                    state.positions_mm[i] =
                        Vec3::new(rest[i].x, rest[i].y, sphere_z(rest[i].x, rest[i].y, depth));
                }
            }
            // A long implicit step is a Newton step towards equilibrium; two of them, at rest each time.
            let mut solver = ImplicitEuler::new(4000);
            for _ in 0..2 {
                solver.step(&model, &mut state, 1.0);
                state.velocities_mm_s.fill(Vec3::zeros());
            }
            model.compute_static_forces(&state.positions_mm, None, &mut internal);
            // Let go of what pulls; take what came through.
            let mut changed = false;
            force_n = 0.0;
            for &i in &top {
                let x = state.positions_mm[i];
                if held[i] {
                    if internal[i].z < 0.0 {
                        held[i] = false;
                        changed = true;
                    } else {
                        force_n += internal[i].z;
                    }
                } else if x.z > sphere_z(x.x, x.y, depth) + 1e-4 {
                    held[i] = true;
                    changed = true;
                }
            }
            positions.clone_from(&state.positions_mm);
            if !changed {
                break;
            }
        }
        forces.push(force_n);
    }
    forces
}

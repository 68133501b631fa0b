//! Corotational FEM step time against tetrahedron count, one core, beside the mass-spring model's implicit step
//! on the same mesh in the same run (the ratio travels between machines; the microseconds do not).
//!
//! Blocks of `c x c x c/2` cubes of 1 mm (six tetrahedra each; the foot fixed), liver-like material (E = 5 kPa,
//! nu = 0.45, 1060 kg/m^3), a patch of the top pushed down by a load that swings at 3 Hz so every step works.
//! Each size times: the element force pass alone; one implicit-Euler step at 1 ms with 20 CG iterations (the
//! shipped fem_block world's setting); and the same step of a mass-spring model of the same mesh. Prints p50 /
//! p99 per size, ns per tetrahedron, the ratio to mass-spring, and the largest size whose step p99 fits 1 ms
//! (a 1 kHz object) and 5 ms (a 200 Hz object).
//!
//! Run: `cargo bench -p sinew-server --bench fem` (options: `--steps N`, default 400; `--cells 8,10,...`;
//! `--dt-ms 5` steps at 5 ms, a 200 Hz multi-rate object's step).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use sinew_protocol::rt::LatencyHistogram;
use sinew_server::tissue::fem::FemMaterial;
use sinew_server::tissue::{
    ImplicitEuler, Integrator, MassSpringModel, ModelParts, TissueState, Vec3,
};
use sinew_server::world::{TetMesh, tet_grid};

const ITERATIONS: u32 = 20;

fn material() -> FemMaterial {
    FemMaterial {
        youngs_modulus_n_per_mm2: 5e-3,
        poisson_ratio: 0.45,
        corotated: true,
    }
}

/// The same mesh as springs: every element's edges at a stiffness of E x edge (about what a cube of E gives).
fn spring_model(fem: &MassSpringModel) -> MassSpringModel {
    let mut parts: ModelParts = fem.to_parts();
    parts.fem = None;
    parts.edge_stiffness_n_per_mm.fill(5e-3);
    MassSpringModel::from_parts(parts)
}

struct Timing {
    forces: LatencyHistogram,
    step: LatencyHistogram,
    iterations: u64,
}

fn time(model: &MassSpringModel, top: &[usize], steps: usize, dt_s: f32) -> Timing {
    let mut state = TissueState::at_rest(model);
    let mut solver = ImplicitEuler::new(ITERATIONS);
    let mut forces = vec![Vec3::zeros(); model.node_count()];
    let mut timing = Timing {
        forces: LatencyHistogram::new(),
        step: LatencyHistogram::new(),
        iterations: 0,
    };
    for k in 0..steps + 50 {
        let load = -2e-3 * (1.0 + (k as f32 * dt_s * 3.0 * std::f32::consts::TAU).sin());
        for &i in top {
            state.external_forces_n[i] = Vec3::new(0.0, 0.0, load);
        }
        let start = Instant::now();
        model.compute_static_forces(
            &state.positions_mm,
            Some(&state.external_forces_n),
            &mut forces,
        );
        let forces_ns = start.elapsed();
        let start = Instant::now();
        let iterations = solver.step(model, &mut state, dt_s);
        let step_ns = start.elapsed();
        assert!(state.is_finite());
        if k >= 50 {
            timing.forces.record(forces_ns);
            timing.step.record(step_ns);
            timing.iterations += u64::from(iterations);
        }
    }
    timing
}

fn main() {
    let steps = bench_args::count_arg("steps", 400).unwrap();
    // `--dt-ms 5`: the step of a 200 Hz multi-rate object (one step a period).
    let dt_s = bench_args::text_arg("dt-ms").map_or(1e-3, |ms| ms.parse::<f32>().unwrap() * 1e-3);
    let cells: Vec<usize> = std::env::args()
        .skip_while(|a| a != "--cells")
        .nth(1)
        .map(|s| s.split(',').map(|c| c.parse().unwrap()).collect())
        .unwrap_or_else(|| vec![6, 8, 10, 12, 14, 18]);
    println!(
        "FEM step against tetrahedron count (implicit Euler, {ITERATIONS} CG iterations, dt {dt_s} s, one core)"
    );
    println!(
        "{:>7} {:>6} | {:>9} {:>9} | {:>9} {:>9} {:>7} | {:>9} {:>7} | {:>5}",
        "tets",
        "nodes",
        "force p50",
        "ns/tet",
        "step p50",
        "step p99",
        "ns/tet",
        "m-s p50",
        "ratio",
        "iters"
    );
    let (mut at_1khz, mut at_200hz) = (0usize, 0usize);
    for &c in &cells {
        let mesh: TetMesh = tet_grid([c, c, c / 2], 1.0).unwrap();
        let h = (c / 2) as f32;
        let fem = common::fem_model(&mesh, material(), 1060.0, |p| p.z < 1e-3);
        let centre = c as f32 / 2.0;
        let top: Vec<usize> = (0..fem.node_count())
            .filter(|&i| {
                let p = fem.rest_positions_mm()[i];
                (p.z - h).abs() < 1e-3 && (p.x - centre).abs() <= 1.0 && (p.y - centre).abs() <= 1.0
            })
            .collect();
        let springs = spring_model(&fem);
        let f = time(&fem, &top, steps, dt_s);
        let s = time(&springs, &top, steps, dt_s);
        let tets = fem.tets().len();
        let (step_p50, step_p99) = (f.step.percentile_us(50.0), f.step.percentile_us(99.0));
        let spring_p50 = s.step.percentile_us(50.0);
        println!(
            "{:>7} {:>6} | {:>7.0}us {:>9.1} | {:>7.0}us {:>7.0}us {:>7.1} | {:>7.0}us {:>6.1}x | {:>5.1}",
            tets,
            fem.node_count(),
            f.forces.percentile_us(50.0),
            f.forces.percentile_us(50.0) * 1e3 / tets as f32,
            step_p50,
            step_p99,
            step_p50 * 1e3 / tets as f32,
            spring_p50,
            step_p50 / spring_p50,
            f.iterations as f64 / steps as f64,
        );
        if step_p99 <= 1000.0 {
            at_1khz = at_1khz.max(tets);
        }
        if step_p99 <= 5000.0 {
            at_200hz = at_200hz.max(tets);
        }
    }
    println!(
        "largest block whose step p99 fits 1 ms (1 kHz): {at_1khz} tets; 5 ms (200 Hz): {at_200hz} tets"
    );
}

//! Every integrator on the classic reference object's size, against the 2001 reference figures.
//!
//! The reference (a 2001 surgical-simulation framework) stepped a 5,000-node, 15,000-edge, 10,000-face object
//! at: Euler 178,000 node / 530,000 edge updates per second, RK2 97,000 / 288,000, RK4 46,000 / 136,000,
//! quasi-static 220,000 / 651,000. The pad (worlds/pad.toml: 4941 nodes, 14540 edges, 9600 faces) is that size.
//! Criterion times one step of each method, stepping continuously from the pad deformed by a probe (one
//! core, warm caches), at dt 1 ms or 0.9x the method's stability bound if smaller; the table after it turns
//! the medians into updates per second and ratios. Then, for implicit Euler and XPBD, the
//! largest step that stays stable at the pad's stiffness beside symplectic Euler's.
//!
//! The same run times a plain scalar array-of-structs symplectic-Euler step of the same pad (the way the 2001
//! framework would have written it, `support/scalar_aos.rs`), and the table gives each method's speed as a
//! ratio to it too: that ratio travels between machines, the microseconds do not.
//!
//! Run: `cargo bench -p sinew-server --bench integrators` (criterion's own report lands in target/criterion).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::{Integrator, MassSpringModel, TissueState, integrator_for};
use sinew_server::world::{IntegratorName, load_world};

#[path = "support/scalar_aos.rs"]
mod scalar_aos;

/// Criterion id of the scalar array-of-structs baseline (`support/scalar_aos.rs`).
const BASELINE: &str = "scalar-aos-symplectic-euler";

/// (method, reference node updates/s, reference edge updates/s) from the 2001 paper.
const REFERENCE: [(IntegratorName, f64, f64); 4] = [
    (IntegratorName::ExplicitEuler, 178_000.0, 530_000.0),
    (IntegratorName::Rk2, 97_000.0, 288_000.0),
    (IntegratorName::Rk4, 46_000.0, 136_000.0),
    (IntegratorName::QuasiStatic, 220_000.0, 651_000.0),
];

/// The pad after a probe pressed 4 mm into it for 0.3 s (a realistic, non-trivial state).
fn pressed_pad() -> (MassSpringModel, TissueState, f32) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let world = load_world(&path).unwrap();
    let mut sim = Sim::new(&world).unwrap();
    let press = ToolCommand {
        active: true,
        position_device_mm: [0.0, 0.0, 0.0], // sphere radius 4: its bottom 4 mm below the rest surface
        velocity_device_mm_s: [0.0; 3],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    };
    let mut out = [ToolOutput::default(); 2];
    for _ in 0..300 {
        sim.step(0.001, &[press, ToolCommand::default()], &mut out);
    }
    let object = sim.objects.swap_remove(0);
    (object.model, object.state, world.objects[0].dt_s)
}

fn median_ns(c: &Criterion, id: &str) -> Option<f64> {
    let _ = c;
    let dir = std::env::var("CARGO_TARGET_DIR").unwrap_or_else(|_| {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../target")
            .to_string_lossy()
            .into_owned()
    });
    let path = std::path::Path::new(&dir)
        .join("criterion/integrator step")
        .join(id)
        .join("new/estimates.json");
    let text = std::fs::read_to_string(path).ok()?;
    // {"mean":{...},"median":{"confidence_interval":{...},"point_estimate":123.4,...
    let at = text.find("\"median\"")?;
    let rest = &text[at..];
    let p = rest.find("\"point_estimate\":")? + "\"point_estimate\":".len();
    let end = rest[p..].find(',')?;
    rest[p..p + end].trim().parse().ok()
}

/// Largest dt (s) for which `method` keeps the pressed pad bounded for 0.2 s of simulated time, by
/// bisection between 10 us and 50 ms.
fn largest_stable_dt_s(
    method: IntegratorName,
    model: &MassSpringModel,
    start: &TissueState,
) -> f64 {
    let stable = |dt: f32| {
        let mut integrator = integrator_for(method, None);
        let mut state = start.clone();
        let steps = ((0.2 / dt).ceil() as usize).max(20);
        let limit = 3.0
            * start
                .positions_mm
                .iter()
                .zip(model.rest_positions_mm())
                .map(|(x, r)| (x - r).norm())
                .fold(0.0, f32::max);
        for _ in 0..steps {
            integrator.step(model, &mut state, dt);
            if !state.is_finite() {
                return false;
            }
        }
        state
            .positions_mm
            .iter()
            .zip(model.rest_positions_mm())
            .all(|(x, r)| (x - r).norm() <= limit)
    };
    let (mut lo, mut hi) = (1e-5f64, 0.05f64);
    if stable(hi as f32) {
        return hi;
    }
    for _ in 0..14 {
        let mid = (lo * hi).sqrt();
        if stable(mid as f32) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

fn main() {
    let (model, state, dt) = pressed_pad();
    let (nodes, edges) = (model.node_count(), model.edge_count());
    let mut c = Criterion::default()
        .configure_from_args()
        .sample_size(60)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    {
        let mut group = c.benchmark_group("integrator step");
        group.throughput(Throughput::Elements(nodes as u64));
        for method in IntegratorName::ALL {
            let mut integrator: Box<dyn Integrator> = integrator_for(method, None);
            // Step continuously from the pressed state, as a simulator does, at a step the method is stable
            // at (explicit Euler and RK2 need a smaller one on the pad; the cost of a step does not depend on
            // its size).
            let dt_method = sinew_server::tissue::stability::max_stable_dt_s(method, &model)
                .map_or(dt, |bound| dt.min(0.9 * bound));
            let mut s = state.clone();
            group.bench_function(BenchmarkId::from_parameter(method.as_str()), |b| {
                b.iter(|| integrator.step(&model, &mut s, dt_method))
            });
            assert!(
                s.is_finite(),
                "{} diverged in its benchmark",
                method.as_str()
            );
        }
        let mut baseline = scalar_aos::ScalarPad::new(&model, &state);
        group.bench_function(BenchmarkId::from_parameter(BASELINE), |b| {
            b.iter(|| baseline.step(dt))
        });
        assert!(baseline.is_finite(), "the scalar baseline diverged");
        group.finish();
    }
    c.final_summary();
    let baseline_ns = median_ns(&c, BASELINE);

    println!(
        "\npad: {nodes} nodes, {edges} edges, {} faces; dt {dt} s; one core; median of criterion samples",
        model.triangles().len()
    );
    println!(
        "| method | us/step | node updates/s | edge updates/s | vs 2001 (nodes) | vs 2001 (edges) | vs scalar AoS, this run |"
    );
    println!("|---|---|---|---|---|---|---|");
    for method in IntegratorName::ALL {
        let Some(ns) = median_ns(&c, method.as_str()) else {
            println!("| {} | (no estimate found) |", method.as_str());
            continue;
        };
        let per_s = 1e9 / ns;
        let reference = REFERENCE.iter().find(|(m, _, _)| {
            *m == method
                || (method == IntegratorName::SymplecticEuler
                    && *m == IntegratorName::ExplicitEuler)
        });
        let (rn, re) = match reference {
            Some((_, n, e)) => (
                format!("{:.0}x", nodes as f64 * per_s / n),
                format!("{:.0}x", edges as f64 * per_s / e),
            ),
            None => ("-".into(), "-".into()),
        };
        let vs_baseline = baseline_ns.map_or("-".into(), |b| format!("{:.2}x", b / ns));
        println!(
            "| {} | {:.1} | {:.1} M | {:.1} M | {rn} | {re} | {vs_baseline} |",
            method.as_str(),
            ns / 1000.0,
            nodes as f64 * per_s / 1e6,
            edges as f64 * per_s / 1e6
        );
    }
    if let Some(b) = baseline_ns {
        let per_s = 1e9 / b;
        println!(
            "| scalar AoS symplectic Euler (baseline) | {:.1} | {:.1} M | {:.1} M | {:.0}x | {:.0}x | 1.00x |",
            b / 1000.0,
            nodes as f64 * per_s / 1e6,
            edges as f64 * per_s / 1e6,
            nodes as f64 * per_s / REFERENCE[0].1,
            edges as f64 * per_s / REFERENCE[0].2
        );
    }
    println!(
        "(symplectic Euler is compared with the reference's Euler; implicit Euler and XPBD have no reference)"
    );

    println!("\nlargest stable dt on the pressed pad (0.2 s simulated, bisection 10 us .. 50 ms):");
    let analytic =
        sinew_server::tissue::stability::max_stable_dt_s(IntegratorName::SymplecticEuler, &model)
            .unwrap_or(f32::NAN);
    for method in [
        IntegratorName::SymplecticEuler,
        IntegratorName::Rk4,
        IntegratorName::ImplicitEuler,
        IntegratorName::Xpbd,
    ] {
        let dt = largest_stable_dt_s(method, &model, &state);
        println!("  {:<17} {:>9.3} ms", method.as_str(), dt * 1e3);
    }
    println!(
        "  (symplectic Euler's loader bound, Gershgorin: {:.3} ms)",
        analytic * 1e3
    );
}

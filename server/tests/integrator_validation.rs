//! Every integrator against analytic answers, not against our own earlier output: a hanging chain's static
//! deflection, an undamped oscillator's period, convergence orders, energy behaviour, stability at stiffness
//! where explicit methods fail, the anti-divergence guard, global volume preservation, spring laws, ties, and
//! every method selectable from a world file.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::f32::consts::TAU;

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::{
    ExplicitEuler, ImplicitEuler, Integrator, MassSpringModel, ModelParts, QuasiStatic, Rk2, Rk4,
    SpringLaw, SymplecticEuler, TissueState, Vec3, Xpbd,
};
use sinew_server::world::{
    FixedSelection, IntegratorName, MassSpec, MaterialSpec, ObjectSpec, SurfaceMesh, World,
    grid_sheet, load_world, parse_world,
};

const G_MM_S2: f32 = 9810.0;

/// A vertical chain: node 0 fixed at the origin, `n` free nodes of `mass_kg` every `spacing_mm` below it,
/// springs of stiffness `k` between neighbours, gravity along -z.
fn chain(n: usize, mass_kg: f32, k: f32, damping: f32, drag: f32) -> MassSpringModel {
    let spacing_mm = 10.0;
    MassSpringModel::from_parts(ModelParts {
        rest_positions_mm: (0..=n)
            .map(|i| Vec3::new(0.0, 0.0, -spacing_mm * i as f32))
            .collect(),
        mass_kg: vec![mass_kg; n + 1],
        fixed: (0..=n).map(|i| i == 0).collect(),
        edges: (0..n as u32).map(|i| [i, i + 1]).collect(),
        edge_stiffness_n_per_mm: vec![k; n],
        edge_damping_n_s_per_mm: vec![damping; n],
        drag_per_s: drag,
        gravity_mm_per_s2: Vec3::new(0.0, 0.0, -G_MM_S2),
        ..ModelParts::default()
    })
}

/// Analytic sag of the chain's last node: spring j (from the top) carries the weight of the `n - j + 1`
/// masses below it, so the total extension is `m g n (n + 1) / (2 k)`.
fn analytic_chain_sag_mm(n: usize, mass_kg: f32, k: f32) -> f32 {
    let weight_n = mass_kg * G_MM_S2 / 1000.0;
    weight_n * (n * (n + 1)) as f32 / 2.0 / k
}

fn settle_chain(integrator: &mut dyn Integrator, dt_s: f32, steps: usize) -> f32 {
    let (n, m, k) = (10, 0.01, 0.5);
    let model = chain(n, m, k, 0.002, 20.0);
    let mut state = TissueState::at_rest(&model);
    for _ in 0..steps {
        integrator.step(&model, &mut state, dt_s);
    }
    let sag = -(state.positions_mm[n].z - model.rest_positions_mm()[n].z);
    let analytic = analytic_chain_sag_mm(n, m, k);
    println!(
        "{}: sag {sag:.4} mm, analytic {analytic:.4} mm, error {:.3}%",
        integrator.name(),
        100.0 * (sag - analytic).abs() / analytic
    );
    (sag - analytic).abs() / analytic
}

#[test]
fn hanging_chain_static_deflection_matches_analytic_within_one_percent() {
    assert!(settle_chain(&mut QuasiStatic::new(50), 0.001, 400) < 0.01);
    assert!(settle_chain(&mut ImplicitEuler::new(60), 0.01, 600) < 0.01);
    // The explicit methods and XPBD reach the same rest state (not required by the issue; a cross-check).
    assert!(settle_chain(&mut SymplecticEuler, 0.0005, 20_000) < 0.01);
    assert!(settle_chain(&mut Xpbd::new(200), 0.01, 300) < 0.01);
}

/// One free node on a spring to a fixed node along x; the free node sits at the origin at rest.
fn oscillator(mass_kg: f32, k: f32) -> MassSpringModel {
    MassSpringModel::from_parts(ModelParts {
        rest_positions_mm: vec![Vec3::new(-10.0, 0.0, 0.0), Vec3::zeros()],
        mass_kg: vec![mass_kg; 2],
        fixed: vec![true, false],
        edges: vec![[0, 1]],
        edge_stiffness_n_per_mm: vec![k],
        edge_damping_n_s_per_mm: vec![0.0],
        ..ModelParts::default()
    })
}

/// m = 0.01 kg, k = 0.1 N/mm: w^2 = 1000 k / m = 1e4 s^-2, w = 100 rad/s, period 62.83 ms.
const OSC_MASS_KG: f32 = 0.01;
const OSC_K: f32 = 0.1;
const OSC_OMEGA: f32 = 100.0;

/// Period from the first and last upward zero crossings of x over `steps`, linearly interpolated.
fn measured_period_s(integrator: &mut dyn Integrator, dt_s: f32, steps: usize) -> f32 {
    let model = oscillator(OSC_MASS_KG, OSC_K);
    let mut state = TissueState::at_rest(&model);
    state.positions_mm[1].x = 1.0;
    let mut crossings = Vec::new();
    let mut previous = state.positions_mm[1].x;
    for k in 1..=steps {
        integrator.step(&model, &mut state, dt_s);
        let x = state.positions_mm[1].x;
        if previous < 0.0 && x >= 0.0 {
            crossings.push((k as f32 - 1.0 + previous / (previous - x)) * dt_s);
        }
        previous = x;
    }
    assert!(
        crossings.len() >= 3,
        "{} did not oscillate",
        integrator.name()
    );
    (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f32
}

#[test]
fn undamped_oscillator_period_matches_two_pi_sqrt_m_over_k_within_one_percent() {
    let analytic = TAU * (OSC_MASS_KG / (OSC_K * 1000.0)).sqrt();
    assert!((analytic - TAU / OSC_OMEGA).abs() < 1e-6);
    let dt = 2e-4; // h w = 0.02
    let methods: [&mut dyn Integrator; 5] = [
        &mut SymplecticEuler,
        &mut Rk2::default(),
        &mut Rk4::default(),
        &mut ImplicitEuler::new(20),
        &mut Xpbd::new(20),
    ];
    for integrator in methods {
        let period = measured_period_s(integrator, dt, 5_000);
        println!(
            "{}: period {:.5} s vs {analytic:.5} s",
            integrator.name(),
            period
        );
        assert!(
            (period - analytic).abs() / analytic < 0.01,
            "{}: {period} vs {analytic}",
            integrator.name()
        );
    }
}

/// |x(T) - A cos(w T)| after T = 0.24 s from x = 1 mm at rest.
fn error_at_t(integrator: &mut dyn Integrator, dt_s: f32) -> f64 {
    let model = oscillator(OSC_MASS_KG, OSC_K);
    let mut state = TissueState::at_rest(&model);
    state.positions_mm[1].x = 1.0;
    let t = 0.24;
    let steps = (t / dt_s).round() as usize;
    for _ in 0..steps {
        integrator.step(&model, &mut state, dt_s);
    }
    let exact = (f64::from(OSC_OMEGA) * f64::from(t)).cos();
    (f64::from(state.positions_mm[1].x) - exact).abs()
}

#[test]
fn runge_kutta_errors_fall_at_their_order_when_dt_halves() {
    // h w = 0.4 then 0.2: large enough that truncation error dwarfs f32 rounding.
    let rk4 = error_at_t(&mut Rk4::default(), 4e-3) / error_at_t(&mut Rk4::default(), 2e-3);
    let rk2 = error_at_t(&mut Rk2::default(), 4e-3) / error_at_t(&mut Rk2::default(), 2e-3);
    let (order4, order2) = (rk4.log2(), rk2.log2());
    println!("observed order: RK4 {order4:.2}, RK2 {order2:.2}");
    assert!((3.6..=4.4).contains(&order4), "RK4 order {order4}");
    assert!((1.7..=2.3).contains(&order2), "RK2 order {order2}");
}

fn oscillator_energy_j(state: &TissueState) -> f64 {
    let v = f64::from(state.velocities_mm_s[1].x) * 1e-3;
    let s = f64::from(state.positions_mm[1].x) * 1e-3;
    0.5 * f64::from(OSC_MASS_KG) * v * v + 0.5 * f64::from(OSC_K) * 1e3 * s * s
}

#[test]
fn symplectic_euler_keeps_energy_bounded_where_explicit_euler_gains_it() {
    let model = oscillator(OSC_MASS_KG, OSC_K);
    let dt = 5e-4; // h w = 0.05
    let mut symplectic = TissueState::at_rest(&model);
    symplectic.positions_mm[1].x = 1.0;
    let mut explicit = symplectic.clone();
    let e0 = oscillator_energy_j(&symplectic);
    let mut worst = 0.0f64;
    for _ in 0..100_000 {
        SymplecticEuler.step(&model, &mut symplectic, dt);
        worst = worst.max((oscillator_energy_j(&symplectic) / e0 - 1.0).abs());
    }
    println!("symplectic Euler: worst relative energy error over 1e5 steps {worst:.4}");
    assert!(worst < 0.05, "symplectic energy drifted by {worst}");
    for _ in 0..2_000 {
        ExplicitEuler.step(&model, &mut explicit, dt);
    }
    // Growth per step is 1 + (h w)^2 = 1.0025: after 2000 steps about e^5 = 148x.
    let growth = oscillator_energy_j(&explicit) / e0;
    println!("explicit Euler: energy x{growth:.1} after 2000 steps");
    assert!(growth > 50.0, "explicit Euler energy grew only {growth}x");
}

/// A square grid sheet, `side` nodes per edge, spacing 2 mm, centred on the origin.
fn sheet_mesh(side: usize) -> SurfaceMesh {
    grid_sheet(side - 1, side - 1, 2.0)
}

fn sheet_spec(side: usize, integrator: IntegratorName, dt_s: f32, k: f32) -> ObjectSpec {
    let half = (side - 1) as f32; // 2 mm cells: half the sheet's width
    ObjectSpec {
        name: "sheet".into(),
        mesh: sheet_mesh(side),
        tets: Vec::new(),
        integrator,
        solver_iterations: None,
        dt_s,
        quant_margin_mm: 10.0,
        delta_tolerance_mm: 0.0,
        triangle_contact: false,
        material: MaterialSpec {
            mass: MassSpec::TotalKg(0.01),
            stiffness_n_per_mm: k,
            damping_n_s_per_mm: 0.0,
            anchor_stiffness_n_per_mm: 0.0,
            drag_per_s: 5.0,
            law: SpringLaw::Linear,
            global_bulk_modulus_n_per_mm2: 0.0,
            tet_bulk_modulus_n_per_mm2: 0.0,
            tear_strain: None,
            cut_resistance_n: MaterialSpec::DEFAULT_CUT_RESISTANCE_N,
            cut_follows_blade: false,
            burn_shrink: 0.0,
            friction_coefficient: 0.0,
            puncture: sinew_server::tissue::PunctureSpec::DEFAULT,
            fem: None,
            calibrated: None,
        },
        fixed: [[-1.0, -half], [1.0, half]]
            .iter()
            .flat_map(|&[sign, at]| {
                (0..2).map(move |axis| {
                    let mut normal = [0.0; 3];
                    normal[axis] = sign;
                    let mut point = [0.0; 3];
                    point[axis] = at;
                    FixedSelection::Plane {
                        point_mm: point,
                        normal,
                        tolerance_mm: 0.01,
                    }
                })
            })
            .collect(),
        region: None,
        ticks_per_step: 1,
    }
}

/// The sheet with its centre node lifted `lift_mm`.
fn lifted_sheet(spec: &ObjectSpec, lift_mm: f32) -> (MassSpringModel, TissueState) {
    let model = MassSpringModel::build(spec, Vec3::zeros());
    let mut state = TissueState::at_rest(&model);
    let side = (model.node_count() as f32).sqrt() as usize;
    state.positions_mm[side * (side / 2) + side / 2].z = lift_mm;
    (model, state)
}

fn max_height_after(integrator: &mut dyn Integrator, spec: &ObjectSpec, steps: usize) -> f32 {
    let (model, mut state) = lifted_sheet(spec, 2.0);
    for _ in 0..steps {
        integrator.step(&model, &mut state, spec.dt_s);
    }
    state
        .positions_mm
        .iter()
        .map(|p| {
            if p.z.is_finite() {
                p.z.abs()
            } else {
                f32::INFINITY
            }
        })
        .fold(0.0, f32::max)
}

#[test]
fn implicit_euler_and_xpbd_stay_stable_where_explicit_methods_diverge() {
    // A stiff sheet at 1 ms: h w is about 5, two and a half times symplectic Euler's limit.
    let spec = sheet_spec(11, IntegratorName::SymplecticEuler, 0.001, 20.0);
    let model = MassSpringModel::build(&spec, Vec3::zeros());
    let bound =
        sinew_server::tissue::stability::max_stable_dt_s(IntegratorName::SymplecticEuler, &model)
            .unwrap();
    println!("symplectic bound {bound:.6} s at dt 0.001 s");
    assert!(spec.dt_s > 2.0 * bound);
    for explicit in [
        &mut SymplecticEuler as &mut dyn Integrator,
        &mut ExplicitEuler,
        &mut Rk4::default(),
    ] {
        let height = max_height_after(explicit, &spec, 500);
        println!("{}: max |z| {height}", explicit.name());
        assert!(height > 100.0, "{} should diverge here", explicit.name());
    }
    for stable in [
        &mut ImplicitEuler::new(40) as &mut dyn Integrator,
        &mut Xpbd::new(10),
        &mut QuasiStatic::new(4),
    ] {
        let height = max_height_after(stable, &spec, 500);
        println!("{}: max |z| {height}", stable.name());
        assert!(height <= 2.0 + 1e-3, "{} grew to {height}", stable.name());
    }
}

fn world_of(objects: Vec<ObjectSpec>) -> World {
    World {
        source: "test".into(),
        scene: "test".into(),
        tick_hz: 1000.0,
        publish_hz: 60.0,
        pose_timeout_s: 0.1,
        collision_margin_mm: 2.0,
        gravity_mm_per_s2: [0.0; 3],
        tissue_threads: None,
        ties: Vec::new(),
        objects,
        tools: Vec::new(),
        exercise: None,
    }
}

#[test]
fn anti_divergence_halves_the_step_and_rescues_an_explicit_run() {
    // Pad-like stiffness; 2.5x symplectic Euler's bound: one halving (to 1.25x) may not be enough, two are.
    let mut spec = sheet_spec(11, IntegratorName::SymplecticEuler, 0.001, 0.015);
    let model = MassSpringModel::build(&spec, Vec3::zeros());
    let bound =
        sinew_server::tissue::stability::max_stable_dt_s(IntegratorName::SymplecticEuler, &model)
            .unwrap();
    spec.dt_s = 2.5 * bound;
    let tick_s = spec.dt_s;
    // Without the guard the run diverges (the same integrator, stepped directly).
    assert!(max_height_after(&mut SymplecticEuler, &spec, 2_000) > 100.0);
    // With it, every tick that starts to blow up is rerun at half the step until it holds.
    let mut sim = Sim::new(&world_of(vec![spec.clone()])).unwrap();
    // A 1 mm lift: node speeds stay physical (about 2 m/s, under the guard's 10 m/s) while the motion is stable.
    let (_, lifted) = lifted_sheet(&spec, 1.0);
    sim.objects[0].state = lifted;
    let (mut retries, mut faults) = (0, 0);
    for _ in 0..2_000 {
        let report = sim.step(tick_s, &[], &mut []);
        retries += report.retries;
        faults += report.faults;
    }
    let height = sim.objects[0]
        .state
        .positions_mm
        .iter()
        .map(|p| p.z.abs())
        .fold(0.0, f32::max);
    println!("guarded: {retries} retries, {faults} faults, max |z| {height}");
    assert_eq!(faults, 0);
    assert!(retries > 0, "the guard never had to act");
    assert!(height.is_finite() && height <= 1.0, "max |z| {height}");
}

#[test]
fn a_run_that_diverges_even_at_the_smallest_step_is_reset_and_counted() {
    // 100x the bound: four halvings (1/16) cannot save it; the object is reset to rest, forces stay finite.
    let mut spec = sheet_spec(11, IntegratorName::SymplecticEuler, 0.001, 0.015);
    let model = MassSpringModel::build(&spec, Vec3::zeros());
    let bound =
        sinew_server::tissue::stability::max_stable_dt_s(IntegratorName::SymplecticEuler, &model)
            .unwrap();
    spec.dt_s = 100.0 * bound;
    let mut sim = Sim::new(&world_of(vec![spec.clone()])).unwrap();
    let (_, lifted) = lifted_sheet(&spec, 1.0);
    sim.objects[0].state = lifted;
    let mut faults = 0;
    for _ in 0..50 {
        faults += sim.step(spec.dt_s, &[], &mut []).faults;
        assert!(sim.objects[0].state.is_finite());
    }
    assert!(faults > 0);
}

/// An icosphere of radius 10 mm (2 subdivisions: 162 nodes, 320 triangles), outward wound.
fn icosphere() -> SurfaceMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|c| Vec3::new(c[0], c[1], c[2]).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..2 {
        let mut midpoints = std::collections::HashMap::new();
        let mut next = Vec::new();
        let mut mid = |a: u32, b: u32, p: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) / 2.0).normalize());
                (p.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let (ab, bc, ca) = (mid(a, b, &mut p), mid(b, c, &mut p), mid(c, a, &mut p));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    SurfaceMesh {
        positions_mm: p
            .iter()
            .map(|v| [10.0 * v.x, 10.0 * v.y, 10.0 * v.z])
            .collect(),
        triangles: tris,
    }
}

/// Squeeze the sphere between its poles with constant forces and relax to equilibrium; returns the
/// relative volume change.
fn squeezed_volume_change(bulk_modulus_n_per_mm2: f32) -> f32 {
    let mesh = icosphere();
    let n = mesh.positions_mm.len();
    let model = MassSpringModel::from_parts({
        let mut edges: Vec<[u32; 2]> = mesh
            .triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| [t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])]))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        ModelParts {
            rest_positions_mm: mesh.positions_mm.iter().map(|p| Vec3::from(*p)).collect(),
            mass_kg: vec![1e-4; n],
            fixed: vec![false; n],
            edge_stiffness_n_per_mm: vec![0.05; edges.len()],
            edge_damping_n_s_per_mm: vec![0.0; edges.len()],
            edges,
            anchor_stiffness_n_per_mm: 1e-4,
            drag_per_s: 50.0,
            triangles: mesh.triangles.clone(),
            global_bulk_modulus_n_per_mm2: bulk_modulus_n_per_mm2,
            ..ModelParts::default()
        }
    });
    let v0 = sinew_server::tissue::volume::enclosed_volume_mm3(
        model.rest_positions_mm(),
        model.triangles(),
    );
    let mut state = TissueState::at_rest(&model);
    for (f, p) in state
        .external_forces_n
        .iter_mut()
        .zip(model.rest_positions_mm())
    {
        // Polar caps pushed toward the equator, 0.02 N per node.
        if p.z.abs() > 8.0 {
            *f = Vec3::new(0.0, 0.0, -0.02 * p.z.signum());
        }
    }
    let mut integrator = ImplicitEuler::new(60);
    for _ in 0..3_000 {
        integrator.step(&model, &mut state, 0.001);
    }
    let v =
        sinew_server::tissue::volume::enclosed_volume_mm3(&state.positions_mm, model.triangles());
    (v - v0) / v0
}

#[test]
fn global_volume_preservation_keeps_a_squeezed_sphere_within_two_percent() {
    let free = squeezed_volume_change(0.0);
    let preserved = squeezed_volume_change(0.05); // 50 kPa
    println!(
        "squeezed sphere volume change: {:.2}% free, {:.2}% with 50 kPa bulk modulus",
        100.0 * free,
        100.0 * preserved
    );
    assert!(
        free < -0.05,
        "the squeeze should lose volume without the term ({free})"
    );
    assert!(preserved.abs() < 0.02, "volume changed {preserved}");
}

#[test]
fn a_stiffening_law_resists_a_large_stretch_more_than_the_linear_one() {
    let stretch = |law: SpringLaw| {
        let mut parts = ModelParts {
            rest_positions_mm: vec![Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0)],
            mass_kg: vec![0.01; 2],
            fixed: vec![true, false],
            edges: vec![[0, 1]],
            edge_stiffness_n_per_mm: vec![0.1],
            edge_damping_n_s_per_mm: vec![0.0],
            law: Some(law),
            drag_per_s: 100.0,
            ..ModelParts::default()
        };
        parts.gravity_mm_per_s2 = Vec3::zeros();
        let model = MassSpringModel::from_parts(parts);
        let mut state = TissueState::at_rest(&model);
        state.external_forces_n[1] = Vec3::new(0.5, 0.0, 0.0); // 0.5 N pull
        let mut integrator = QuasiStatic::new(20);
        for _ in 0..500 {
            integrator.step(&model, &mut state, 0.001);
        }
        state.positions_mm[1].x - 10.0
    };
    let linear = stretch(SpringLaw::Linear);
    let piecewise = stretch(SpringLaw::PiecewiseLinear {
        knee_strain: 0.1,
        stiffness_ratio: 4.0,
    });
    let exponential = stretch(SpringLaw::Exponential { stiffening: 5.0 });
    println!(
        "0.5 N pull: linear {linear:.3} mm, piecewise {piecewise:.3} mm, exponential {exponential:.3} mm"
    );
    // Linear: 0.5 / 0.1 = 5 mm. Piecewise: 1 mm at k, then 0.4 N at 4k = 1 mm more: 2 mm.
    assert!((linear - 5.0).abs() < 0.01);
    assert!((piecewise - 2.0).abs() < 0.01);
    // Exponential: k L / b (e^(b s / L) - 1) = 0.5  =>  s = L / b ln(1 + 0.5 b / (k L)) = 2 ln(3.5).
    assert!((exponential - 2.0 * 3.5f32.ln()).abs() < 0.01);
}

const TWO_OBJECT_WORLD: &str = r#"
scene = "ties"

[[objects]]
name = "skin"
mesh = "meshes/pad.obj"
units = "mm"
integrator = "symplectic-euler"
dt_s = 0.001
material = { mass_kg = 0.6, stiffness_n_per_mm = 0.015, damping_n_s_per_mm = 0.000003, anchor_stiffness_n_per_mm = 0.0, drag_per_s = 150.0 }
fixed = [{ kind = "plane", point_mm = [-39.0, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }]

[[objects]]
name = "bone"
mesh = "meshes/pad.obj"
units = "mm"
integrator = "symplectic-euler"
dt_s = 0.001
material = { mass_kg = 0.6, stiffness_n_per_mm = 0.015, damping_n_s_per_mm = 0.000003, anchor_stiffness_n_per_mm = 0.008, drag_per_s = 150.0 }

[[ties]]
objects = ["skin", "bone"]
within_mm = 0.01
stiffness_n_per_mm = 0.02
"#;

#[test]
fn ties_pass_force_from_one_object_to_the_other() {
    let worlds = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/ties.toml");
    let world = parse_world(&worlds, TWO_OBJECT_WORLD).unwrap();
    assert_eq!(world.ties.len(), 1);
    assert_eq!(
        world.ties[0].pairs.len(),
        world.objects[0].mesh.positions_mm.len()
    );
    let mut sim = Sim::new(&world).unwrap();
    // Pull the skin's centre node up 3 mm and hold it there: the bone under it must follow.
    let centre = sim.objects[0]
        .model
        .rest_positions_mm()
        .iter()
        .position(|p| p.x.abs() < 0.5 && p.y.abs() < 0.5 && p.z.abs() < 0.5)
        .unwrap();
    for _ in 0..300 {
        sim.objects[0].state.positions_mm[centre].z = 3.0;
        sim.objects[0].state.velocities_mm_s[centre] = Vec3::zeros();
        sim.note_state_changed();
        sim.step(0.001, &[], &mut []);
    }
    let bone_z = sim.objects[1].state.positions_mm[centre].z;
    println!("bone node under the lifted skin: z = {bone_z:.3} mm");
    assert!(bone_z > 0.05, "the tie did not pull the bone ({bone_z})");
    // Unknown object names are refused with the key.
    let bad = TWO_OBJECT_WORLD.replace(
        r#"objects = ["skin", "bone"]"#,
        r#"objects = ["skin", "muscle"]"#,
    );
    let error = parse_world(&worlds, &bad).unwrap_err().to_string();
    assert!(
        error.contains("ties[0].objects") && error.contains("unknown object"),
        "{error}"
    );
}

#[test]
fn every_integrator_is_selectable_from_the_world_file_and_probes_the_pad() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("integrator = \"symplectic-euler\""));
    // Text, not a scene edit: this is the world file's `integrator` key under test (each method's name parses
    // and selects it, and a step too large for it is refused naming `dt_s`), so the file is patched.
    for method in IntegratorName::ALL {
        let mut world_text = text.replace(
            "integrator = \"symplectic-euler\"",
            &format!("integrator = \"{}\"", method.as_str()),
        );
        let world = match parse_world(&path, &world_text) {
            Ok(world) => world,
            Err(e) => {
                // Explicit methods need a smaller step on the pad: the loader says so; take a quarter.
                let message = e.to_string();
                assert!(message.contains("dt_s"), "{}: {message}", method.as_str());
                world_text = world_text.replace("dt_s = 0.001", "dt_s = 0.0001");
                parse_world(&path, &world_text)
                    .unwrap_or_else(|e| panic!("{}: {e}", method.as_str()))
            }
        };
        assert_eq!(world.objects[0].integrator, method);
        let mut sim = Sim::new(&world).unwrap();
        assert_eq!(sim.objects[0].integrator_name(), method.as_str());
        let press = ToolCommand {
            active: true,
            position_device_mm: [0.0, 0.0, 4.0 - 3.0],
            velocity_device_mm_s: [0.0; 3],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..ToolCommand::default()
        };
        let mut out = [ToolOutput::default(); 2];
        for _ in 0..300 {
            let report = sim.step(0.001, &[press, ToolCommand::default()], &mut out);
            assert_eq!(report.faults, 0, "{}", method.as_str());
        }
        let f = out[0].force_world_n;
        println!("{}: force at 3 mm {:?} N", method.as_str(), f.as_slice());
        assert!(
            f.z > 0.05 && f.iter().all(|c| c.is_finite()),
            "{}: {f:?}",
            method.as_str()
        );
    }
    let _ = load_world(&path).unwrap();
}

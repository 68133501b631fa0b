//! A 1-D rod (the suture thread, `tissue::RodSpec`) is an object the engine steps like any other: every
//! integrator, through the same guarded step and divergence guard as the tick's objects. A thread fixed at one
//! end falls from horizontal and hangs straight down, at its rest length.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::tissue::{
    DivergenceGuard, Integrator, IntegratorName, MassSpringModel, RodError, RodSpec, Stepped,
    TissueState, Vec3, integrator_for, stability::max_stable_dt_s, step_guarded,
};

const GRAVITY_MM_PER_S2: [f32; 3] = [0.0, 0.0, -9810.0];

/// One rod stepped by one integrator under the guard, as a multi-rate job steps its object.
struct RodStepper {
    model: MassSpringModel,
    state: TissueState,
    integrator: Box<dyn Integrator>,
    guard: DivergenceGuard,
}

impl Stepped for RodStepper {
    fn integrate(&mut self, h_s: f32, substeps: u32) {
        for _ in 0..substeps {
            self.integrator.step(&self.model, &mut self.state, h_s);
        }
    }

    fn judge(&mut self) -> (bool, f64) {
        let a = self.guard.assess(&self.model, &self.state);
        (a.broken, a.energy_n_mm)
    }

    fn restore(&mut self) {
        self.guard.restore(&mut self.state);
    }
}

/// A 50 mm thread of ten segments along +x, its first node fixed.
fn thread() -> RodSpec {
    RodSpec {
        mass_per_length_kg_per_mm: 1e-6,
        axial_rigidity_n: 5.0,
        drag_per_s: 20.0,
        fixed_nodes: vec![0],
        ..RodSpec::straight("thread", [0.0; 3], [50.0, 0.0, 0.0], 10)
    }
}

#[test]
fn a_thread_fixed_at_one_end_hangs_straight_down_with_every_integrator() {
    for method in IntegratorName::ALL {
        let spec = thread();
        let model = spec.model(Vec3::from(GRAVITY_MM_PER_S2)).unwrap();
        assert!(model.triangles().is_empty());
        assert_eq!(model.node_count(), 11);
        assert_eq!(
            model.edge_count(),
            10 + 9,
            "ten stretch springs and nine bend springs"
        );
        let tick_s = 0.001f32;
        // Explicit methods substep below their stability bound, as the tick plans an object's substeps.
        let planned = max_stable_dt_s(method, &model)
            .map_or(1, |bound| (tick_s / (0.5 * bound)).ceil().max(1.0) as u32);
        let mut rod = RodStepper {
            state: TissueState::at_rest(&model),
            integrator: integrator_for(method, None),
            guard: DivergenceGuard::new(&model).with_max_displacement_mm(spec.guard_reach_mm()),
            model,
        };
        let mut energy = rod.judge().1;
        let mut gave_up = 0;
        for _ in 0..3000 {
            rod.guard.save(&rod.state);
            let step = step_guarded(&mut rod, tick_s, planned, energy, 0.0);
            gave_up += u32::from(step.gave_up());
            energy = step.energy_n_mm;
        }
        let name = method.as_str();
        assert_eq!(gave_up, 0, "{name}: the guard gave up on a hanging thread");
        assert!(rod.state.is_finite(), "{name}");
        let x = &rod.state.positions_mm;
        let end = x[10];
        if method == IntegratorName::QuasiStatic {
            // Relaxation without inertia moves each node by its force over its springs' stiffness a sweep:
            // micrometres for a thread swinging on its fixed end, whose equilibrium is a large rotation away.
            // It steps the rod stably and downhill, but hanging it takes a million sweeps: a thread is not a
            // quasi-static object.
            assert!(
                end.z < 0.0 && (end - Vec3::new(50.0, 0.0, 0.0)).norm() < 1.0,
                "{name}: {end:?}"
            );
            println!("{name}: end {end:?} (relaxing, as it should, slowly)");
            continue;
        }
        assert!(
            end.x.abs() < 1.0 && end.y.abs() < 1e-3 && (-50.5..-49.0).contains(&end.z),
            "{name}: the free end hangs at {end:?}, not 50 mm below the fixed end"
        );
        for s in 0..10 {
            let length_mm = (x[s + 1] - x[s]).norm();
            assert!(
                (length_mm - 5.0).abs() < 0.05,
                "{name}: segment {s} is {length_mm} mm, not its 5 mm rest length"
            );
        }
        // Settled: what still moves is the last of the swing under drag.
        let fastest = rod
            .state
            .velocities_mm_s
            .iter()
            .map(|v| v.norm())
            .fold(0.0, f32::max);
        assert!(
            fastest < 5.0,
            "{name}: still moving at {fastest} mm/s after 3 s"
        );
        println!("{name}: end {end:?}, {planned} substeps a tick, fastest {fastest:.3} mm/s");
    }
}

#[test]
fn a_bad_rod_is_refused_naming_what_is_wrong() {
    let g = Vec3::from(GRAVITY_MM_PER_S2);
    let one = RodSpec {
        nodes_mm: vec![[0.0; 3]],
        ..thread()
    };
    assert_eq!(
        one.parts(g).unwrap_err(),
        RodError::TooFewNodes("thread".into())
    );
    let mut nan = thread();
    nan.nodes_mm[3][1] = f32::NAN;
    assert!(matches!(
        nan.parts(g),
        Err(RodError::NonFinite { node: 3, .. })
    ));
    let mut doubled = thread();
    doubled.nodes_mm[5] = doubled.nodes_mm[4];
    assert!(matches!(
        doubled.parts(g),
        Err(RodError::ZeroSegment { segment: 4, .. })
    ));
    let weightless = RodSpec {
        mass_per_length_kg_per_mm: 0.0,
        ..thread()
    };
    let message = weightless.parts(g).unwrap_err().to_string();
    assert!(
        message.contains("mass_per_length_kg_per_mm must be positive"),
        "{message}"
    );
    let far = RodSpec {
        fixed_nodes: vec![11],
        ..thread()
    };
    assert!(matches!(
        far.parts(g),
        Err(RodError::FixedOutOfRange {
            node: 11,
            nodes: 11,
            ..
        })
    ));
    let slack = RodSpec {
        damping_n_s_per_mm: -1.0,
        ..thread()
    };
    assert!(
        slack
            .parts(g)
            .unwrap_err()
            .to_string()
            .contains("damping_n_s_per_mm")
    );
}

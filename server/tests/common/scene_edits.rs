//! Scenes built in code: a test loads a world file once, unmodified, and changes typed fields of the [`World`]
//! it got (`world.objects[0].material.friction_coefficient = 0.5;`) instead of patching the file's text.
//!
//! Most edits are one assignment. The ones here are those where the world file's key does more than set one
//! field, or where the loader refuses some values: each does what the loader does with that key (the same
//! derivation, the same acceptance rule) and panics where the loader would have refused the world, so a
//! scene built here is one the world file could have described.
#![allow(dead_code)] // each test binary uses its own subset

use sinew_server::tissue::{IntegratorName, ObjectSpec, RegionParams};
use sinew_server::world::World;

/// The most ticks one step of a multi-rate object may span (the world loader's `MAX_TICKS_PER_STEP`).
const MAX_TICKS_PER_STEP: f64 = 100.0;

/// The most substeps an object may take in one step (the world loader's `MAX_SUBSTEPS`).
const MAX_SUBSTEPS: f32 = 1000.0;

/// Object `object`'s step period, s: its ticks per step of the world's tick period, which the loader takes
/// as `(1 / tick_hz) as f32`.
fn step_period_s(world: &World, spec: &ObjectSpec) -> f32 {
    (1.0 / world.tick_hz) as f32 * spec.ticks_per_step as f32
}

/// Whether the world loader accepts `dt_s` for `spec` in `world`: within its step period and at least
/// 1/[`MAX_SUBSTEPS`] of it, and no larger than its integrator's stability bound at its stiffness, damping and
/// mass under the world's gravity ([`ObjectSpec::max_stable_dt_s`], the bound the loader checks).
pub fn dt_accepted(world: &World, spec: &ObjectSpec, dt_s: f32) -> bool {
    let period = step_period_s(world, spec);
    let in_period = dt_s > 0.0 && dt_s <= period * (1.0 + 1e-6) && dt_s >= period / MAX_SUBSTEPS;
    in_period
        && dt_s
            <= spec
                .max_stable_dt_s(world.gravity_mm_per_s2)
                .unwrap_or(f32::INFINITY)
}

/// Object `object` integrated by `method` at the first step of `ladder` (seconds, largest first) that the
/// world loader accepts for it ([`dt_accepted`]), as a world file with `integrator = "<method>"` tried at each
/// `dt_s` of the ladder in turn. Make the object's other edits first: its stiffness, damping and mass set the
/// bound. Panics where the loader refuses the method on this object, or every step of the ladder.
pub fn with_integrator(
    mut world: World,
    object: usize,
    method: IntegratorName,
    ladder: &[f32],
) -> World {
    let spec = &mut world.objects[object];
    // The loader's refusals of a method whatever the step.
    assert!(
        !(spec.material.fem.is_some() && method == IntegratorName::Xpbd),
        "the loader refuses xpbd on finite elements"
    );
    assert!(
        spec.solver_iterations.is_none()
            || !matches!(
                method,
                IntegratorName::ExplicitEuler
                    | IntegratorName::SymplecticEuler
                    | IntegratorName::Rk2
                    | IntegratorName::Rk4
            ),
        "the loader refuses solver_iterations with {}",
        method.as_str()
    );
    spec.integrator = method;
    let spec = &world.objects[object];
    let dt_s = ladder
        .iter()
        .copied()
        .find(|&dt| dt_accepted(&world, spec, dt))
        .unwrap_or_else(|| {
            panic!(
                "`{}` with {} takes none of the steps {ladder:?}",
                spec.name,
                method.as_str()
            )
        });
    world.objects[object].dt_s = dt_s;
    world
}

/// Object `object` stepped at `step_hz` with steps of `dt_s`, as a world file's `step_hz` and `dt_s` keys set
/// them: `ticks_per_step` is the loader's (the tick rate recovered from the f32 tick period, over `step_hz`,
/// rounded), and the loader's checks hold (a whole number of ticks a step, at most 100; `dt_s` within the step
/// period; a multi-rate object with no region, tearing, burn shrink or tie). Panics where the loader would
/// refuse.
pub fn with_step_hz(mut world: World, object: usize, step_hz: f64, dt_s: f32) -> World {
    let tick_hz = 1.0 / f64::from((1.0 / world.tick_hz) as f32);
    assert!(
        step_hz.is_finite() && step_hz > 0.0 && step_hz <= tick_hz * (1.0 + 1e-6),
        "step_hz {step_hz} is not a positive rate no higher than the tick's"
    );
    let ratio = tick_hz / step_hz;
    let ticks = ratio.round();
    assert!(
        (ratio - ticks).abs() <= 1e-6 * ratio && ticks <= MAX_TICKS_PER_STEP,
        "step_hz {step_hz} does not divide the tick rate a whole number of times, at most {MAX_TICKS_PER_STEP}"
    );
    let spec = &mut world.objects[object];
    spec.ticks_per_step = ticks as u32;
    spec.dt_s = dt_s;
    let spec = &world.objects[object];
    assert!(
        dt_accepted(&world, spec, dt_s),
        "the loader refuses dt_s = {dt_s} for `{}` at {step_hz} Hz",
        spec.name
    );
    if spec.ticks_per_step > 1 {
        assert!(
            spec.region.is_none(),
            "a multi-rate object cannot be region-tracked"
        );
        assert!(
            spec.material.tear_strain.is_none() && spec.material.burn_shrink == 0.0,
            "a multi-rate object cannot tear or shrink"
        );
        assert!(
            world
                .ties
                .iter()
                .all(|t| t.object_a != object && t.object_b != object),
            "a multi-rate object cannot be tied"
        );
    }
    world
}

/// Object `object` region-tracked at `threshold_mm`, as a world file's `region = { threshold_mm }` sets it,
/// where the loader accepts it (a threshold in (0, 1] mm; no global volume term; no gravity; an object stepped
/// every tick and tied to none). Panics where it would refuse.
pub fn with_region(mut world: World, object: usize, threshold_mm: f32) -> World {
    let spec = &world.objects[object];
    assert!(
        threshold_mm.is_finite() && threshold_mm > 0.0 && threshold_mm <= 1.0,
        "region threshold {threshold_mm} mm is not in (0, 1]"
    );
    assert_eq!(
        spec.material.global_bulk_modulus_n_per_mm2, 0.0,
        "a region cannot be combined with a global volume term"
    );
    assert_eq!(
        world.gravity_mm_per_s2, [0.0; 3],
        "a region needs a world without gravity"
    );
    assert_eq!(
        spec.ticks_per_step, 1,
        "a multi-rate object cannot be region-tracked"
    );
    assert!(
        world
            .ties
            .iter()
            .all(|t| t.object_a != object && t.object_b != object),
        "a tied object cannot be region-tracked"
    );
    world.objects[object].region = Some(RegionParams { threshold_mm });
    world
}

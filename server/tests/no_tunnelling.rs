//! A tool never ends up under a thin surface (issue "Safe under faults", items 4 and 5): not after a pose
//! jump across the pad, not when a device joins while its hand already presses into the pad (a server
//! restart), and not when it rejoins after a gap long enough to release the tool (a partition). Each time the
//! pad pushes back up, and on a (re)join the force grows to its steady value without overshooting by more
//! than 10%.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

fn pad() -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    Sim::new(&load_world(&path).expect("pad world loads")).expect("pad builds")
}

/// The left probe (sphere, radius 4 mm) with its centre at `z_mm` over the pad's rest surface (z = 0).
fn at(z_mm: f32, active: bool) -> [ToolCommand; 2] {
    let left = ToolCommand {
        active,
        position_device_mm: [0.0, 0.0, z_mm],
        velocity_device_mm_s: [0.0; 3],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    };
    let right = ToolCommand {
        active: false,
        ..left
    };
    [left, right]
}

/// Run `seconds` of 1 ms ticks; the left tool's upward force at every tick, N.
fn run(sim: &mut Sim, commands: &[ToolCommand; 2], seconds: f32) -> Vec<f32> {
    let mut out = [ToolOutput::default(); 2];
    (0..(seconds * 1000.0) as usize)
        .map(|_| {
            let report = sim.step(0.001, commands, &mut out);
            assert_eq!(report.faults, 0);
            out[0].force_world_n.z
        })
        .collect()
}

fn steady(forces: &[f32]) -> f32 {
    let tail = &forces[forces.len() - 200..];
    tail.iter().sum::<f32>() / tail.len() as f32
}

/// Pressing 5 mm (centre 1 mm below the rest surface) the pad pushes back about this much, N.
fn reference_press_n() -> f32 {
    let mut sim = pad();
    run(&mut sim, &at(10.0, true), 0.2);
    // Descend from 10 mm above to the press over 0.5 s, then hold.
    for k in 1..=500 {
        run(&mut sim, &at(10.0 - 11.0 * k as f32 / 500.0, true), 0.001);
    }
    steady(&run(&mut sim, &at(-1.0, true), 1.0))
}

#[test]
fn a_20_mm_pose_jump_across_the_pad_from_above_leaves_the_pad_pushing_back() {
    let mut sim = pad();
    let free = run(&mut sim, &at(10.0, true), 0.3);
    assert!(
        free.iter().all(|f| *f == 0.0),
        "touching the pad from 6 mm above"
    );
    // One tick: from 10 mm above the pad to 10 mm below it.
    let forces = run(&mut sim, &at(-10.0, true), 1.5);
    let held = steady(&forces);
    assert!(
        held > 0.5,
        "after the jump the pad pushes up with only {held:.3} N: the tool crossed the sheet"
    );
    assert!(
        forces.iter().all(|f| *f >= -1e-3),
        "the pad pulled the tool down"
    );
}

#[test]
fn a_probe_pressed_20_mm_into_the_pad_never_passes_through_it() {
    // A slow press (20 mm/s) from 10 mm above to 20 mm below the surface, then a 1 s hold. Before the
    // contact was sided the sheet closed over the probe 12-16 mm down and the force fell to 0 N for good.
    let mut sim = pad();
    let mut forces = run(&mut sim, &at(10.0, true), 0.1);
    for k in 1..=1500 {
        forces.extend(run(&mut sim, &at(10.0 - 0.02 * k as f32, true), 0.001));
    }
    forces.extend(run(&mut sim, &at(-20.0, true), 1.0));
    let touched = forces
        .iter()
        .position(|f| *f > 0.05)
        .expect("the probe reached the pad");
    // Deeper is firmer: the force never falls below 80% of the most it has reached.
    let mut most = 0.0f32;
    let mut worst_drop = (0usize, 1.0f32);
    for (tick, f) in forces.iter().enumerate().skip(touched) {
        most = most.max(*f);
        let kept = *f / most;
        if kept < worst_drop.1 {
            worst_drop = (tick, kept);
        }
    }
    println!(
        "deep press: touched at tick {touched}, least kept {:.3} of the peak at tick {}, end {:.3} N",
        worst_drop.1,
        worst_drop.0,
        steady(&forces)
    );
    assert!(
        worst_drop.1 > 0.8,
        "the pad let go of the probe: at tick {} the force was {:.3} of its peak so far",
        worst_drop.0,
        worst_drop.1
    );
    assert!(
        steady(&forces) > 2.0,
        "20 mm deep the pad pushes only {:.3} N",
        steady(&forces)
    );
}

#[test]
fn a_device_that_joins_while_pressing_finds_the_pad_on_top_and_the_force_does_not_overshoot() {
    let reference = reference_press_n();
    assert!(reference > 0.3, "reference press {reference:.3} N");
    // A fresh server (a restart): its first pose from this device is already 5 mm into the pad.
    let mut sim = pad();
    let forces = run(&mut sim, &at(-1.0, true), 1.5);
    let held = steady(&forces);
    let peak = forces.iter().fold(0.0f32, |a, f| a.max(*f));
    println!(
        "join while pressing: steady {held:.3} N (reference {reference:.3} N), peak {peak:.3} N"
    );
    assert!(
        (held - reference).abs() <= 0.1 * reference,
        "joined pressing: {held:.3} N against {reference:.3} N for the same press made from above"
    );
    assert!(
        peak <= 1.1 * held,
        "the force overshot to {peak:.3} N on the way to {held:.3} N"
    );
}

#[test]
fn a_device_that_rejoins_after_a_gap_while_pressing_finds_the_pad_on_top() {
    let mut sim = pad();
    run(&mut sim, &at(10.0, true), 0.2);
    for k in 1..=500 {
        run(&mut sim, &at(10.0 - 11.0 * k as f32 / 500.0, true), 0.001);
    }
    let before = steady(&run(&mut sim, &at(-1.0, true), 1.0));
    // The device goes quiet (its tool is released, the pad relaxes), then comes back pressing where it was.
    run(&mut sim, &at(-1.0, false), 1.0);
    let forces = run(&mut sim, &at(-1.0, true), 1.5);
    let after = steady(&forces);
    let peak = forces.iter().fold(0.0f32, |a, f| a.max(*f));
    println!("rejoin: {before:.3} N before the gap, {after:.3} N after, peak {peak:.3} N");
    assert!(
        (after - before).abs() <= 0.1 * before,
        "after the gap the pad pushes {after:.3} N, before it {before:.3} N"
    );
    assert!(
        peak <= 1.1 * after,
        "the force overshot to {peak:.3} N on the way to {after:.3} N"
    );
}

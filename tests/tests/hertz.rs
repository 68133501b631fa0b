//! Hertz contact (issue "Tissue from material data"): a rigid 8 mm sphere pressed 0.5-3 mm into a large block
//! of E = 10 kPa, nu = 0.45 follows F = 4/3 E* sqrt(R) d^1.5 within 10%, for the corotational FEM and for the
//! calibrated springs alike (the machinery and the mesh: `sinew_testkit::hertz`). Each model's error is printed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)] // test code

use sinew_testkit::hertz::{Material, block_parts, hertz_n, press};

const DEPTHS_MM: [f32; 3] = [0.5, 1.5, 3.0];

/// Press the block of `material` to each depth; print and return each error against Hertz (fraction).
fn errors_against_hertz(material: Material) -> Vec<f32> {
    let parts = block_parts(material).unwrap();
    let forces = press(&parts, &DEPTHS_MM);
    DEPTHS_MM
        .iter()
        .zip(&forces)
        .map(|(&d, &f)| {
            let h = hertz_n(d);
            println!(
                "{}: {d} mm: {f:.4} N, Hertz {h:.4} N ({:+.1}%)",
                material.label(),
                (f / h - 1.0) * 100.0
            );
            f / h - 1.0
        })
        .collect()
}

fn assert_within_10_percent(material: Material) {
    for (d, error) in DEPTHS_MM.iter().zip(errors_against_hertz(material)) {
        assert!(
            error.abs() < 0.10,
            "{} at {d} mm is {:+.1}% from Hertz",
            material.label(),
            error * 100.0
        );
    }
}

#[test]
fn a_sphere_pressed_into_a_large_fem_block_follows_hertz_within_10_percent() {
    assert_within_10_percent(Material::Fem);
}

#[test]
fn a_sphere_pressed_into_calibrated_springs_follows_hertz_within_10_percent() {
    assert_within_10_percent(Material::CalibratedSprings);
}

#[test]
fn the_force_a_hand_feels_from_a_multi_rate_fem_block_follows_hertz() {
    // Not the static solve: the simulation itself, the block stepping at 25 Hz on its pinned-contact steps and
    // the indenter's force rendered every tick from the local model of its latest step.
    let forces = sinew_testkit::hertz::sim_press(Material::Fem, 25, &DEPTHS_MM).unwrap();
    for (&d, &f) in DEPTHS_MM.iter().zip(&forces) {
        let h = hertz_n(d);
        println!(
            "FEM at 25 Hz in the simulation: {d} mm: {f:.4} N, Hertz {h:.4} N ({:+.1}%)",
            (f / h - 1.0) * 100.0
        );
        assert!(
            (f / h - 1.0).abs() < 0.10,
            "{d} mm: {f} N against Hertz {h} N"
        );
    }
}

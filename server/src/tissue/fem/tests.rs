//! Unit tests of the finite elements: rotations, forces against the energy, corotation, and the stiffness
//! product against the force change.

use nalgebra::UnitQuaternion;

use super::polar::rotation_of_any;
use super::*;

/// A unit cube of 6 tetrahedra around its main diagonal, scaled to `size` mm.
fn cube(size: f32) -> (Vec<Vec3>, TetVolumes) {
    let x: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * size)
        .collect();
    let tets = crate::tissue::KUHN.map(|t| t.map(|i| i as u32));
    let (volumes, dropped) = TetVolumes::new(&tets, &x, 0.0);
    assert_eq!(dropped, 0);
    (x, volumes)
}

fn material(corotated: bool) -> FemMaterial {
    FemMaterial {
        youngs_modulus_n_per_mm2: 5e-3,
        poisson_ratio: 0.45,
        corotated,
    }
}

fn elements(corotated: bool) -> (Vec<Vec3>, TetVolumes, FemElements) {
    let (x, tets) = cube(3.0);
    let mut fem = FemElements::default();
    fem.refill(Some(material(corotated)), &tets, &x);
    (x, tets, fem)
}

#[test]
fn rotation_of_a_rotation_is_itself_and_of_a_stretch_is_identity() {
    let q = UnitQuaternion::from_euler_angles(0.3, -1.2, 2.9);
    let r = q.to_rotation_matrix().into_inner();
    assert!((rotation_of(&r) - r).norm() < 1e-5);
    let s = Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.1);
    assert!((rotation_of(&s) - Matrix3::identity()).norm() < 1e-4);
    assert!((rotation_of(&(r * s)) - r).norm() < 1e-4);
    // Large stretch and shear on the fast path, and the same through the robust one.
    let sheared = r * Matrix3::new(1.6, 0.4, 0.0, 0.4, 0.7, 0.3, 0.0, 0.3, 1.2);
    assert!((rotation_of(&sheared) - r).norm() < 1e-4);
    assert!((rotation_of_any(&sheared) - r).norm() < 1e-4);
    // Inverted and degenerate gradients still give a rotation.
    for m in [
        Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, -1.0)),
        Matrix3::zeros(),
    ] {
        let r = rotation_of(&m);
        assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-4);
        assert!((r.determinant() - 1.0).abs() < 1e-4);
    }
}

#[test]
fn forces_are_minus_the_energy_gradient() {
    for corotated in [true, false] {
        let (mut x, tets, fem) = elements(corotated);
        let (mut start, mut list) = (vec![0u32], Vec::new());
        for i in 0..8u32 {
            list.extend((0..6u32).filter(|&t| tets.tets[t as usize].contains(&i)));
            start.push(list.len() as u32);
        }
        let incident = NodeTets {
            start: &start,
            tets: &list,
        };
        x[7] += Vec3::new(0.4, -0.3, 0.5);
        x[2] += Vec3::new(-0.2, 0.1, 0.3);
        let mut f = vec![Vec3::zeros(); 8];
        fem.accumulate_forces(&tets, &x, &mut f, None);
        for node in [2usize, 7] {
            let one = fem.node_force(node, &tets, incident, &x);
            assert!((one - f[node]).norm() < 1e-6, "{one} vs {}", f[node]);
            for axis in 0..3 {
                let h = 1e-3;
                let (mut plus, mut minus) = (x.clone(), x.clone());
                plus[node][axis] += h;
                minus[node][axis] -= h;
                let numeric = -(fem.energy_n_mm(&tets, &plus) - fem.energy_n_mm(&tets, &minus))
                    / (2.0 * f64::from(h));
                let analytic = f64::from(f[node][axis]);
                assert!(
                    (analytic - numeric).abs() < 2e-3 * analytic.abs().max(1e-3),
                    "corotated {corotated}, node {node}, axis {axis}: {analytic} vs {numeric}"
                );
            }
        }
        let total: Vec3 = f.iter().sum();
        assert!(total.norm() < 1e-6);
    }
}

#[test]
fn a_rigid_rotation_strains_a_corotated_element_only() {
    let q = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f32::consts::FRAC_PI_2);
    for (corotated, strained) in [(true, false), (false, true)] {
        let (x, tets, fem) = elements(corotated);
        let turned: Vec<Vec3> = x.iter().map(|p| q * p).collect();
        let mut f = vec![Vec3::zeros(); 8];
        fem.accumulate_forces(&tets, &turned, &mut f, None);
        let largest = f.iter().map(|v| v.norm()).fold(0.0, f32::max);
        // Scale: E x area x unit strain on a 3 mm cube, 0.045 N.
        assert_eq!(
            largest > 1e-3,
            strained,
            "corotated {corotated}: {largest} N"
        );
    }
}

#[test]
fn the_stiffness_product_matches_the_force_change() {
    let (mut x, tets, fem) = elements(true);
    x[7] += Vec3::new(0.2, -0.1, 0.3);
    let mut lin = FemLinearization::default();
    fem.linearize(&tets, &x, &mut lin);
    let p: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i as f32 * 0.7).sin(), (i as f32 * 1.3).cos(), 0.2) * 1e-3)
        .collect();
    let mut kp = vec![Vec3::zeros(); 8];
    fem.add_stiffness_product(&tets, &mut lin, &p, 1.0, &mut kp);
    let moved: Vec<Vec3> = x.iter().zip(&p).map(|(a, b)| a + b).collect();
    let (mut f0, mut f1) = (vec![Vec3::zeros(); 8], vec![Vec3::zeros(); 8]);
    fem.accumulate_forces(&tets, &x, &mut f0, None);
    fem.accumulate_forces(&tets, &moved, &mut f1, None);
    // K p ~ -(f(x + p) - f(x)), up to the rotation's change (left out of K) and second order.
    let scale = kp.iter().map(|v| v.norm()).fold(0.0, f32::max);
    for i in 0..8 {
        let df = f1[i] - f0[i];
        assert!(
            (kp[i] + df).norm() < 0.1 * scale,
            "node {i}: {} vs {}",
            kp[i],
            -df
        );
    }
}

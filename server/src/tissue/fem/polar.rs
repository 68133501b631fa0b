//! Each element's rotation: the rotation `R` of the polar decomposition `F = R S` of its deformation
//! gradient, fast for the common element and robust for an inverted or flat one.
//!
//! Owns: [`rotation_of`] and its robust fallback. Must not: know about elements, nodes or forces (a pure
//! function of one matrix, so forces never depend on history).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

use crate::tissue::Vec3;

/// Most Newton polar-decomposition iterations per element (two to four reach f32 precision at tissue strains).
const POLAR_ITERATIONS: usize = 8;

/// Most iterations of the robust polar decomposition (inverted or flat elements only; it converges linearly).
const ROBUST_ITERATIONS: usize = 32;

/// The rotation of `f`'s polar decomposition `f = R S`. An element that is neither inverted nor nearly flat
/// takes Higham's Newton iteration (converged to 1e-6); any other takes the iteration of Müller, Bender,
/// Chentanez and Macklin ("A robust method to extract the rotational part of deformations", MIG 2016),
/// started from the Gram-Schmidt frame of `f`'s first two columns, which always gives a rotation. A pure
/// function of `f`: the same input gives the same bits, so forces never depend on history.
pub fn rotation_of(f: &Matrix3<f32>) -> Matrix3<f32> {
    // The common case, an element that is not inverted or flat: Higham's Newton iteration
    // `R <- (R + R^-T) / 2` from `R = F`, quadratic (two to four iterations at tissue strains).
    let det = f.determinant();
    if det > 1e-3 * f.norm_squared().powf(1.5) {
        let mut r = *f;
        for _ in 0..POLAR_ITERATIONS {
            let Some(inverse) = r.try_inverse() else {
                break;
            };
            let next = (r + inverse.transpose()) * 0.5;
            let change = (next - r).norm_squared();
            if !change.is_finite() {
                break;
            }
            r = next;
            if change < 1e-12 {
                return r;
            }
        }
    }
    rotation_of_any(f)
}

/// [`rotation_of`] for any `f`, also inverted or degenerate: Müller et al.'s iteration from the Gram-Schmidt
/// frame of `f`'s first two columns.
pub(super) fn rotation_of_any(f: &Matrix3<f32>) -> Matrix3<f32> {
    let (c0, c1) = (f.column(0).into_owned(), f.column(1).into_owned());
    let guess = c0.try_normalize(1e-20).and_then(|e0| {
        let e1 = (c1 - e0 * e0.dot(&c1)).try_normalize(1e-20)?;
        Some(Matrix3::from_columns(&[e0, e1, e0.cross(&e1)]))
    });
    // Closed form from an orthonormal frame (`UnitQuaternion::from_matrix` would iterate from the identity).
    let mut q = match guess {
        Some(m) => UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
        None => UnitQuaternion::identity(),
    };
    if !q.coords.iter().all(|c| c.is_finite()) {
        q = UnitQuaternion::identity();
    }
    for _ in 0..ROBUST_ITERATIONS {
        let r = q.to_rotation_matrix().into_inner();
        let mut axis = Vec3::zeros();
        let mut denom = 0.0;
        for k in 0..3 {
            let (rk, fk) = (r.column(k), f.column(k));
            axis += rk.cross(&fk);
            denom += rk.dot(&fk);
        }
        let omega = axis / (denom.abs() + 1e-9);
        // Converged (or not finite): 1e-6 rad is below what f32 strains resolve.
        let turn_squared = omega.norm_squared();
        if turn_squared.is_nan() || turn_squared < 1e-12 {
            break;
        }
        // Turn by `omega` (first order: the quaternion (1, omega / 2), renormalised; no trigonometry).
        let turn = nalgebra::Quaternion::new(1.0, omega.x * 0.5, omega.y * 0.5, omega.z * 0.5);
        q = UnitQuaternion::new_normalize(turn * q.into_inner());
    }
    q.to_rotation_matrix().into_inner()
}

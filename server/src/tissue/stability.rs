//! The largest stable step of each explicit method for a given model, from the linear test equation.
//!
//! Each node's stiffness and damping rates are bounded by Gershgorin ([`MassSpringModel::node_rates`]); the
//! worst node's modes are the test equations `x'' = -w^2 x - g x'` (scaled down over a grid, since lower modes
//! carry proportionally less edge damping), and a step is stable when the method's 2x2 amplification matrix
//! has spectral radius <= 1 for every one of them. Implicit Euler, quasi-static relaxation and XPBD have no
//! bound. Pure functions; used by the world loader, never in a tick.

use super::IntegratorName;
use super::MassSpringModel;

/// Strain up to which a stiffening law's tangent is assumed when bounding the step (beyond it, the
/// anti-divergence guard halves the step at run time).
pub const DESIGN_STRAIN: f32 = 0.3;

/// 2x2 real matrix, row-major.
type M2 = [[f64; 2]; 2];

fn mul(a: M2, b: M2) -> M2 {
    let mut c = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    c
}

fn spectral_radius(m: M2) -> f64 {
    let trace = m[0][0] + m[1][1];
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let disc = trace * trace - 4.0 * det;
    if disc >= 0.0 {
        let r = disc.sqrt();
        ((trace + r) / 2.0).abs().max(((trace - r) / 2.0).abs())
    } else {
        det.abs().sqrt()
    }
}

/// One step's amplification matrix on `(x, v)` for `x'' = -omega2 x - gamma_edge x' - drag x'`.
pub fn amplification(
    method: IntegratorName,
    h: f64,
    omega2: f64,
    gamma_edge: f64,
    drag: f64,
) -> Option<M2> {
    let gamma = gamma_edge + drag;
    let a: M2 = [[0.0, h], [-h * omega2, -h * gamma]];
    let taylor = |order: u32| {
        let mut term: M2 = [[1.0, 0.0], [0.0, 1.0]];
        let mut sum = term;
        for k in 1..=order {
            term = mul(term, a);
            for row in &mut term {
                for c in row.iter_mut() {
                    *c /= f64::from(k);
                }
            }
            for i in 0..2 {
                for j in 0..2 {
                    sum[i][j] += term[i][j];
                }
            }
        }
        sum
    };
    match method {
        IntegratorName::ExplicitEuler => Some(taylor(1)),
        IntegratorName::Rk2 => Some(taylor(2)),
        IntegratorName::Rk4 => Some(taylor(4)),
        IntegratorName::SymplecticEuler => {
            // v1 = (v0 + h(-w^2 x0 - g_e v0)) / (1 + h d); x1 = x0 + h v1.
            let s = 1.0 / (1.0 + h * drag);
            let v_row = [-h * omega2 * s, (1.0 - h * gamma_edge) * s];
            Some([[1.0 + h * v_row[0], h * v_row[1]], v_row])
        }
        IntegratorName::QuasiStatic | IntegratorName::ImplicitEuler | IntegratorName::Xpbd => None,
    }
}

/// The largest `h` (s, at most 1) at which `method` is stable on every mode of `model`; `None` for methods
/// without a bound; a rounding-level value when no real step is stable (explicit Euler or RK2 on an
/// undamped object).
pub fn max_stable_dt_s(method: IntegratorName, model: &MassSpringModel) -> Option<f32> {
    amplification(method, 1e-3, 1.0, 0.0, 0.0)?;
    let stiffening = model.law().stiffening_at(DESIGN_STRAIN);
    let (mut omega2_max, mut ratio_min, mut ratio_max) = (0.0f64, f64::INFINITY, 0.0f64);
    for (omega2, gamma_edge) in model.node_rates(stiffening) {
        let (omega2, gamma_edge) = (f64::from(omega2), f64::from(gamma_edge));
        omega2_max = omega2_max.max(omega2);
        if omega2 > 0.0 {
            ratio_min = ratio_min.min(gamma_edge / omega2);
            ratio_max = ratio_max.max(gamma_edge / omega2);
        }
    }
    if omega2_max == 0.0 {
        return Some(1.0);
    }
    let drag = f64::from(model.drag_per_s());
    let stable = |h: f64| {
        (0..=40).all(|k| {
            let scale = 0.5f64.powf(f64::from(k) / 4.0); // 1 down to 1e-3
            let omega2 = omega2_max * scale;
            [ratio_min, ratio_max].iter().all(|ratio| {
                amplification(method, h, omega2, ratio * omega2, drag)
                    .is_some_and(|m| spectral_radius(m) <= 1.0 + 1e-9)
            })
        })
    };
    if stable(1.0) {
        return Some(1.0);
    }
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) { lo = mid } else { hi = mid }
    }
    Some(lo as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bound(method: IntegratorName, omega2: f64, gamma: f64, drag: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, 10.0);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            let m = amplification(method, mid, omega2, gamma, drag).unwrap();
            if spectral_radius(m) <= 1.0 + 1e-12 {
                lo = mid
            } else {
                hi = mid
            }
        }
        lo
    }

    #[test]
    fn textbook_bounds_for_an_undamped_oscillator() {
        // w = 1: symplectic Euler h < 2, RK4 h < 2 sqrt(2); explicit Euler and RK2 never.
        assert!((bound(IntegratorName::SymplecticEuler, 1.0, 0.0, 0.0) - 2.0).abs() < 1e-6);
        assert!((bound(IntegratorName::Rk4, 1.0, 0.0, 0.0) - 8f64.sqrt()).abs() < 1e-3);
        // Their growth per step is 1 + h^2/2 and 1 + h^4/8: only rounding-level steps pass the 1e-12 test.
        assert!(bound(IntegratorName::ExplicitEuler, 1.0, 0.0, 0.0) < 1e-5);
        assert!(bound(IntegratorName::Rk2, 1.0, 0.0, 0.0) < 1e-2);
    }

    #[test]
    fn damping_makes_explicit_euler_stable_up_to_g_over_w2() {
        // Underdamped: |1 + h lambda|^2 = 1 - h g + h^2 w^2 <= 1  <=>  h <= g / w^2.
        let h = bound(IntegratorName::ExplicitEuler, 100.0, 2.0, 0.0);
        assert!((h - 0.02).abs() < 1e-6, "{h}");
    }
}

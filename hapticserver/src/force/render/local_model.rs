//! The linear part of a local model: `f = f0 - K (x - x0) - D v`, one-sided along the contact normal and faded
//! out towards the model's radius.
//!
//! Owns: [`linear_force_n`] and its fade ([`fade_weight`]), and the drag of cutting ([`cut_drag_force_n`]). Must not: touch the planes (that is
//! [`super::plane_proxy`]), keep state, blend between models ([`super::blend`]), or clamp for safety.

use sinew_protocol::messages::local_model::sym3_mul;
use sinew_protocol::{CUT_DRAG_SMOOTHING_MM_S, LocalModel};

use super::{MAX_DRAG_PER_NORMAL, all_finite, dot3};

/// Below this `|f0|` (N) a model has no contact normal and its linear part renders zero.
pub const MIN_CONTACT_FORCE_N: f32 = 1e-6;

/// The linear part of `model` at the device position `position_mm` moving at `velocity_mm_s` (device frame), N.
///
/// Zero unless `model.in_contact` and (for a one-sided model) `|f0| > MIN_CONTACT_FORCE_N`. With the contact
/// normal `n = f0 / |f0|` and the spring part `s = f0 - K (x - x0)`:
/// - with `model.attached` (the tool holds tissue) the result is `s - D v`, faded: held tissue pulls back
///   whichever way the tool moves, so none of the one-sided rules below apply;
/// - `n . s <= 0`: the tool has left the tissue, exactly zero (tissue never pulls);
/// - otherwise `f = s - D v`, where everything but the elastic normal part `(n . s) n` (the tangential spring
///   and the damping) is capped in magnitude at [`MAX_DRAG_PER_NORMAL`] `* (n . s)`, so the force falls
///   continuously to zero at release instead of stepping by the sideways spring or `D v`; then the component
///   along `n` is clamped to `>= 0` (damping never pulls);
/// - the result is scaled by [`fade_weight`] of `|x - x0|`: full inside `radius - fade`, smoothly to zero at
///   the radius, zero beyond.
///
/// For a fixed model the result is Lipschitz: a step `dx`, `dv` changes it by at most
/// `(2 + c) |K| |dx| + |D| |dv| + 1.5 / fade * (1 + c) * (|f0| + |K| (radius + |dx|)) * |dx|`, with
/// `c = MAX_DRAG_PER_NORMAL` and `|.|` the spectral norm (see the property test in [`super::blend`]).
///
/// Real-time contract: no allocation, never blocks, never panics; the result is always finite (zero when any
/// input is not).
pub fn linear_force_n(
    model: &LocalModel,
    position_mm: [f32; 3],
    velocity_mm_s: [f32; 3],
) -> [f32; 3] {
    const ZERO: [f32; 3] = [0.0; 3];
    if !model.in_contact {
        return ZERO;
    }
    let f0 = model.f0_n;
    let offset_mm: [f32; 3] = std::array::from_fn(|i| position_mm[i] - model.x0_mm[i]);
    let weight = fade_weight(
        dot3(offset_mm, offset_mm).sqrt(),
        model.radius_mm,
        model.fade_mm,
    );
    if weight.is_nan() || weight <= 0.0 {
        return ZERO;
    }
    let k_dx_n = sym3_mul(&model.stiffness_n_per_mm, &offset_mm);
    let spring_n: [f32; 3] = std::array::from_fn(|i| f0[i] - k_dx_n[i]);
    let d_v_n = sym3_mul(&model.damping_n_s_per_mm, &velocity_mm_s);
    if model.attached {
        // Held tissue pulls back whichever way the tool moves: no one-sided cut-off, no drag cap, and no
        // contact normal needed (a needle just through its hole, or a grasp at rest, holds with `f0` near
        // zero).
        let force_n: [f32; 3] = std::array::from_fn(|i| weight * (spring_n[i] - d_v_n[i]));
        return if all_finite(force_n) { force_n } else { ZERO };
    }
    let f0_norm_n = dot3(f0, f0).sqrt();
    if !f0_norm_n.is_finite() || f0_norm_n <= MIN_CONTACT_FORCE_N {
        return ZERO;
    }
    let normal = f0.map(|c| c / f0_norm_n);
    let spring_normal_n = dot3(normal, spring_n);
    if spring_normal_n.is_nan() || spring_normal_n <= 0.0 {
        return ZERO;
    }
    // Everything but the elastic normal part: the tangential spring and the damping.
    let drag_n: [f32; 3] =
        std::array::from_fn(|i| spring_n[i] - spring_normal_n * normal[i] - d_v_n[i]);
    let drag_norm_n = dot3(drag_n, drag_n).sqrt();
    let drag_cap_n = MAX_DRAG_PER_NORMAL * spring_normal_n;
    let drag_scale = if drag_norm_n > drag_cap_n {
        drag_cap_n / drag_norm_n
    } else {
        1.0
    };
    let mut force_n: [f32; 3] =
        std::array::from_fn(|i| spring_normal_n * normal[i] + drag_scale * drag_n[i]);
    let along_normal_n = dot3(normal, force_n);
    if along_normal_n < 0.0 {
        for (f, n) in force_n.iter_mut().zip(normal) {
            *f -= along_normal_n * n;
        }
    }
    let force_n = force_n.map(|c| weight * c);
    if all_finite(force_n) { force_n } else { ZERO }
}

/// The drag of cutting at the device's velocity `velocity_mm_s`, N: `-F v / sqrt(|v|^2 + v_s^2)` with
/// `F = model.cut_drag_n` and `v_s` = [`CUT_DRAG_SMOOTHING_MM_S`]. Always against the motion (it only takes
/// energy out of the hand), continuous in `v` (no step as the hand stops or turns), at most `F`. Not faded at
/// the radius: it acts wherever the hand is while the server says the blade cuts, and ends with the model
/// that says it no longer does (blended like any model change).
///
/// Real-time contract: no allocation, never panics; finite (zero when any input is not).
pub fn cut_drag_force_n(model: &LocalModel, velocity_mm_s: [f32; 3]) -> [f32; 3] {
    let drag_n = model.cut_drag_n;
    if !(drag_n.is_finite() && drag_n > 0.0) {
        return [0.0; 3];
    }
    let smoothing = CUT_DRAG_SMOOTHING_MM_S * CUT_DRAG_SMOOTHING_MM_S;
    let scale = drag_n / (dot3(velocity_mm_s, velocity_mm_s) + smoothing).sqrt();
    let force_n = velocity_mm_s.map(|v| -scale * v);
    if all_finite(force_n) {
        force_n
    } else {
        [0.0; 3]
    }
}

/// How much of the linear part applies at distance `r_mm` from `x0`: 1 up to `radius - fade`, a smoothstep
/// from 1 to 0 over `[radius - fade, radius]`, 0 from the radius on (and for non-finite input).
///
/// Continuous, with slope at most `1.5 / fade_mm` per mm. Real-time contract: no allocation, never panics.
pub fn fade_weight(r_mm: f32, radius_mm: f32, fade_mm: f32) -> f32 {
    if r_mm.is_nan() || r_mm >= radius_mm {
        return 0.0;
    }
    if r_mm <= radius_mm - fade_mm {
        return 1.0;
    }
    let t = ((radius_mm - r_mm) / fade_mm).clamp(0.0, 1.0);
    let weight = t * t * (3.0 - 2.0 * t);
    if weight.is_nan() { 0.0 } else { weight }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In contact at the origin, 1 N along +z, `K = 0.2 I` N/mm, no damping, radius 10 mm, fade 2 mm.
    fn pressing_model() -> LocalModel {
        LocalModel {
            in_contact: true,
            f0_n: [0.0, 0.0, 1.0],
            stiffness_n_per_mm: [0.2, 0.2, 0.2, 0.0, 0.0, 0.0],
            radius_mm: 10.0,
            fade_mm: 2.0,
            ..LocalModel::default()
        }
    }

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
    }

    #[test]
    fn pressing_in_adds_stiffness_times_depth() {
        let model = pressing_model();
        for depth_mm in [0.0f32, 0.5, 3.0, 7.0] {
            let f = linear_force_n(&model, [0.0, 0.0, -depth_mm], [0.0; 3]);
            assert!(
                close(f, [0.0, 0.0, 1.0 + 0.2 * depth_mm], 1e-5),
                "depth {depth_mm}: {f:?}"
            );
        }
    }

    #[test]
    fn pulling_out_past_release_is_exactly_zero() {
        // Release where 1 - 0.2 z = 0: z = 5 mm.
        let model = pressing_model();
        let before = linear_force_n(&model, [0.0, 0.0, 4.9], [0.0; 3]);
        assert!(close(before, [0.0, 0.0, 0.02], 1e-5), "{before:?}");
        for z_mm in [5.0f32, 5.01, 6.0, 7.9] {
            assert_eq!(linear_force_n(&model, [0.0, 0.0, z_mm], [0.0; 3]), [0.0; 3]);
            // Also while moving out fast, and moving in.
            assert_eq!(
                linear_force_n(&model, [0.0, 0.0, z_mm], [0.0, 0.0, -300.0]),
                [0.0; 3]
            );
        }
    }

    #[test]
    fn damping_resists_approach_and_never_pulls() {
        let model = LocalModel {
            damping_n_s_per_mm: [0.05, 0.05, 0.05, 0.0, 0.0, 0.0],
            ..pressing_model()
        };
        // Moving in at 10 mm/s: 0.5 N more (under the drag cap of 1 N).
        let f = linear_force_n(&model, [0.0; 3], [0.0, 0.0, -10.0]);
        assert!(close(f, [0.0, 0.0, 1.5], 1e-5), "{f:?}");
        // Moving out at 10 mm/s: 0.5 N less.
        let f = linear_force_n(&model, [0.0; 3], [0.0, 0.0, 10.0]);
        assert!(close(f, [0.0, 0.0, 0.5], 1e-5), "{f:?}");
        // Moving out fast, in any direction with an outward part: the normal component stays >= 0 (without the
        // clamp it would be 1 - 0.05 * 1000 = -49 N).
        let mut rng = fastrand::Rng::with_seed(7);
        for _ in 0..10_000 {
            let v: [f32; 3] = [
                rng.f32() * 2000.0 - 1000.0,
                rng.f32() * 2000.0 - 1000.0,
                rng.f32() * 1000.0,
            ];
            let x: [f32; 3] = [
                rng.f32() * 4.0 - 2.0,
                rng.f32() * 4.0 - 2.0,
                rng.f32() * 8.0 - 4.0,
            ];
            let f = linear_force_n(&model, x, v);
            assert!(f[2] >= -1e-6, "x {x:?} v {v:?}: {f:?}");
        }
    }

    #[test]
    fn release_with_a_sideways_offset_is_continuous() {
        // 3 mm sideways the tangential spring pulls back with 0.6 N; without the drag cap this would step from
        // 0.6 N to 0 where the normal force crosses zero (z = 5 mm).
        let model = pressing_model();
        let firm = linear_force_n(&model, [3.0, 0.0, 0.0], [0.0; 3]);
        assert!(close(firm, [-0.6, 0.0, 1.0], 1e-5), "{firm:?}");
        let mut previous = firm;
        let mut max_step_n = 0.0f32;
        for i in 1..=700 {
            let z_mm = i as f32 * 0.01;
            let f = linear_force_n(&model, [3.0, 0.0, z_mm], [0.0; 3]);
            let step: [f32; 3] = std::array::from_fn(|k| f[k] - previous[k]);
            max_step_n = max_step_n.max(dot3(step, step).sqrt());
            previous = f;
        }
        assert_eq!(previous, [0.0; 3]);
        // Normal part falls 0.002 N per step, the capped drag as much: |step| <= 0.0029 N.
        assert!(max_step_n < 0.003, "max step {max_step_n} N");
    }

    #[test]
    fn fade_is_continuous_full_inside_and_zero_beyond() {
        // No stiffness: only the fade changes the force. Radius 4 mm, fade 1 mm.
        let model = LocalModel {
            stiffness_n_per_mm: [0.0; 6],
            radius_mm: 4.0,
            fade_mm: 1.0,
            ..pressing_model()
        };
        let mut previous = linear_force_n(&model, [0.0; 3], [0.0; 3]);
        let mut max_step_n = 0.0f32;
        for i in 1..=600 {
            let r_mm = i as f32 * 0.01;
            let f = linear_force_n(&model, [r_mm, 0.0, 0.0], [0.0; 3]);
            if r_mm <= 2.999 {
                assert_eq!(f, [0.0, 0.0, 1.0], "r {r_mm}");
            }
            if r_mm >= 4.0 {
                assert_eq!(f, [0.0; 3], "r {r_mm}");
            }
            max_step_n = max_step_n.max((f[2] - previous[2]).abs());
            previous = f;
        }
        let half = linear_force_n(&model, [3.5, 0.0, 0.0], [0.0; 3]);
        assert!(close(half, [0.0, 0.0, 0.5], 1e-5), "{half:?}");
        // Smoothstep slope is at most 1.5 / fade: 0.015 N per 0.01 mm step (a hard cut would step 1 N).
        assert!(max_step_n <= 0.0151, "max step {max_step_n} N");
    }

    #[test]
    fn zero_f0_or_no_contact_renders_zero() {
        let zero_f0 = LocalModel {
            f0_n: [0.0; 3],
            damping_n_s_per_mm: [0.05, 0.05, 0.05, 0.0, 0.0, 0.0],
            ..pressing_model()
        };
        let not_in_contact = LocalModel {
            in_contact: false,
            ..pressing_model()
        };
        for x in [[0.0, 0.0, -3.0], [0.0; 3], [1.0, 2.0, 3.0]] {
            assert_eq!(linear_force_n(&zero_f0, x, [0.0, 0.0, -50.0]), [0.0; 3]);
            assert_eq!(linear_force_n(&not_in_contact, x, [0.0; 3]), [0.0; 3]);
        }
    }

    #[test]
    fn an_attached_model_pulls_back_both_ways() {
        // A grasp pulled 2 mm up: f0 pulls down with 0.4 N; K = 0.2 I.
        let model = LocalModel {
            attached: true,
            f0_n: [0.0, 0.0, -0.4],
            ..pressing_model()
        };
        // Pulled further up: more pull. Pushed back down past x0 + 2 mm: it pushes up (the held tissue is
        // compressed), where a one-sided model would render exactly zero.
        let up = linear_force_n(&model, [0.0, 0.0, 1.0], [0.0; 3]);
        assert!(close(up, [0.0, 0.0, -0.6], 1e-5), "{up:?}");
        let down = linear_force_n(&model, [0.0, 0.0, -3.0], [0.0; 3]);
        assert!(close(down, [0.0, 0.0, 0.2], 1e-5), "{down:?}");
        // Sideways: the full tangential stiffness, no drag cap (a 5 mm slide would be capped at 0.4 N).
        let side = linear_force_n(&model, [5.0, 0.0, 0.0], [0.0; 3]);
        assert!(close(side, [-1.0, 0.0, -0.4], 1e-5), "{side:?}");
        let unattached = LocalModel {
            attached: false,
            ..model
        };
        assert_eq!(
            linear_force_n(&unattached, [0.0, 0.0, -3.0], [0.0; 3]),
            [0.0; 3]
        );
        // Still faded at the radius.
        assert_eq!(linear_force_n(&model, [0.0, 0.0, 10.0], [0.0; 3]), [0.0; 3]);
    }

    #[test]
    fn the_cut_drag_opposes_motion_is_bounded_and_continuous_through_a_stop() {
        let model = LocalModel {
            cut_drag_n: 0.15,
            ..LocalModel::default()
        };
        let fast = cut_drag_force_n(&model, [0.0, 40.0, 0.0]);
        assert!(
            fast[1] < -0.149 && fast[1] >= -0.15 && fast[0] == 0.0,
            "{fast:?}"
        );
        assert_eq!(cut_drag_force_n(&model, [0.0; 3]), [0.0; 3]);
        let mut rng = fastrand::Rng::with_seed(3);
        for _ in 0..10_000 {
            let v: [f32; 3] = std::array::from_fn(|_| rng.f32() * 200.0 - 100.0);
            let f = cut_drag_force_n(&model, v);
            assert!(
                dot3(f, v) <= 0.0 && dot3(f, f).sqrt() <= 0.15 + 1e-6,
                "{v:?}: {f:?}"
            );
        }
        // Through a stop at 1 mm/s^2 per tick the force changes by at most F / v_s per mm/s.
        let mut previous = cut_drag_force_n(&model, [0.0, 5.0, 0.0]);
        for i in 1..=100 {
            let f = cut_drag_force_n(&model, [0.0, 5.0 - 0.1 * i as f32, 0.0]);
            assert!((f[1] - previous[1]).abs() <= 0.15 / 2.0 * 0.1 + 1e-6);
            previous = f;
        }
        let none = LocalModel {
            cut_drag_n: f32::NAN,
            ..model
        };
        assert_eq!(cut_drag_force_n(&none, [0.0, 5.0, 0.0]), [0.0; 3]);
    }

    #[test]
    fn fade_weight_of_non_finite_input_is_zero() {
        assert_eq!(fade_weight(f32::NAN, 4.0, 1.0), 0.0);
        assert_eq!(fade_weight(3.5, f32::NAN, 1.0), 0.0);
        assert_eq!(fade_weight(3.5, 4.0, f32::NAN), 0.0);
        assert_eq!(fade_weight(f32::INFINITY, 4.0, 1.0), 0.0);
    }

    #[test]
    fn non_finite_input_renders_zero() {
        let model = pressing_model();
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(linear_force_n(&model, [0.0, bad, 0.0], [0.0; 3]), [0.0; 3]);
            assert_eq!(linear_force_n(&model, [0.0; 3], [bad, 0.0, 0.0]), [0.0; 3]);
        }
    }
}

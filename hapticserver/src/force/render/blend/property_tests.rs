//! Randomized property tests of [`ModelRenderer`](super::ModelRenderer): random models swapped in at random
//! (bursts, clears, rotating plane frames) under a random device walk must render finite forces whose step per
//! tick stays within a Lipschitz bound of the motion plus the blend's decay; random planes in general position
//! must keep the god-object proxy's invariants.
//!
//! Owns: the random generators (PSD matrices, unit vectors, frames, models, the device walk) and the Lipschitz
//! bound of a model's force.
//!
//! Must not: test a fixed scenario (those are the parent's `tests`, next to the renderer), or change the
//! seeds: each test is deterministic.

use sinew_protocol::LocalModel;
use sinew_protocol::messages::{ContactPlane, MAX_CONTACT_PLANES};

use super::tests::{DT_S, norm, renderer, sub};
use super::{ModelRenderer, RenderConfig};
use crate::render::{MAX_DRAG_PER_NORMAL, all_finite, dot3};

/// Spectral norm bound of a PSD [`sinew_protocol::Sym3`]: its trace.
fn psd_norm_bound(m: &[f32; 6]) -> f32 {
    m[0] + m[1] + m[2]
}

/// `A^T A` for a random `A` with entries in `[-scale, scale]`, as a Sym3.
fn random_psd(rng: &mut fastrand::Rng, scale: f32) -> [f32; 6] {
    let a: [[f32; 3]; 3] =
        std::array::from_fn(|_| std::array::from_fn(|_| (rng.f32() * 2.0 - 1.0) * scale));
    let m = |r: usize, c: usize| (0..3).map(|k| a[k][r] * a[k][c]).sum::<f32>();
    [m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)]
}

fn random_unit(rng: &mut fastrand::Rng) -> [f32; 3] {
    loop {
        let v: [f32; 3] = std::array::from_fn(|_| rng.f32() * 2.0 - 1.0);
        let n = norm(v);
        if n > 0.1 && n <= 1.0 {
            return v.map(|c| c / n);
        }
    }
}

/// A random orthonormal frame (rows).
fn random_frame(rng: &mut fastrand::Rng) -> [[f32; 3]; 3] {
    let a = random_unit(rng);
    let b = loop {
        let c = random_unit(rng);
        let along = dot3(a, c);
        let d: [f32; 3] = std::array::from_fn(|i| c[i] - along * a[i]);
        if norm(d) > 0.1 {
            break d.map(|x| x / norm(d));
        }
    };
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    [a, b, c]
}

/// A random valid model around `near_mm`; planes along `normals` (each possibly flipped) when given.
fn random_model(rng: &mut fastrand::Rng, near_mm: [f32; 3], normals: &[[f32; 3]]) -> LocalModel {
    let x0_mm: [f32; 3] = std::array::from_fn(|i| near_mm[i] + rng.f32() * 10.0 - 5.0);
    let f0_dir = random_unit(rng);
    let f0_mag_n = rng.f32() * 3.0;
    let radius_mm = 2.0 + rng.f32() * 13.0;
    let mut planes = [ContactPlane::default(); MAX_CONTACT_PLANES];
    let plane_count = rng.usize(0..=normals.len().min(MAX_CONTACT_PLANES));
    for (plane, normal) in planes.iter_mut().zip(normals).take(plane_count) {
        let sign = if rng.bool() { 1.0 } else { -1.0 };
        let normal = normal.map(|c| sign * c);
        let through: [f32; 3] = std::array::from_fn(|i| near_mm[i] + rng.f32() * 6.0 - 3.0);
        *plane = ContactPlane {
            normal,
            offset_mm: dot3(normal, through),
            stiffness_n_per_mm: rng.f32(),
            damping_n_s_per_mm: rng.f32() * 0.02,
        };
    }
    let model = LocalModel {
        server_time_ns: 0,
        in_contact: rng.f32() < 0.8,
        x0_mm,
        f0_n: f0_dir.map(|c| c * f0_mag_n),
        stiffness_n_per_mm: random_psd(rng, 0.3),
        damping_n_s_per_mm: random_psd(rng, 0.05),
        radius_mm,
        fade_mm: 0.1 + rng.f32() * (radius_mm - 0.1),
        planes,
        plane_count: plane_count as u8,
        energy_allowance_mj: 0.0,
        attached: rng.f32() < 0.3,
        cut_drag_n: if rng.bool() { rng.f32() * 0.3 } else { 0.0 },
        friction_coefficient: if rng.bool() { rng.f32() } else { 0.0 },
        stick_stiffness_n_per_mm: rng.f32() * 3.0,
        cut_facet_mm: if rng.bool() {
            0.2 + rng.f32() * 2.0
        } else {
            0.0
        },
        // A needle's pop is a step by design (the tissue gives way): `puncture_pop`'s own tests cover it.
        puncture: sinew_protocol::PunctureTerm::default(),
    };
    assert!(model.validate().is_ok(), "{model:?}");
    model
}

/// The walk's top speed, mm/s.
const MAX_WALK_SPEED_MM_S: f32 = 300.0;

/// The device: a random walk in velocity (steps of up to 5.7 mm/s per axis per tick, speed <= 300 mm/s),
/// pulled weakly back to the origin.
struct Walk {
    position_mm: [f32; 3],
    velocity_mm_s: [f32; 3],
}

impl Walk {
    fn step(&mut self, rng: &mut fastrand::Rng) {
        for i in 0..3 {
            self.velocity_mm_s[i] += (rng.f32() * 2.0 - 1.0) * 5.7;
        }
        let speed = norm(self.velocity_mm_s);
        if speed > MAX_WALK_SPEED_MM_S {
            self.velocity_mm_s = self.velocity_mm_s.map(|c| c * MAX_WALK_SPEED_MM_S / speed);
        }
        // Pulled gently back to the origin so models keep meeting the device.
        for i in 0..3 {
            self.velocity_mm_s[i] -= 0.01 * self.position_mm[i];
            self.position_mm[i] += self.velocity_mm_s[i] * DT_S as f32;
        }
    }
}

/// Lipschitz constants `(per mm, per mm/s)` of a model's force (the renderer without blend) over a step of
/// `dx_mm`, with `c = MAX_DRAG_PER_NORMAL`, `|K| <= trace K`, `|D| <= trace D` (PSD):
/// - linear part: the elastic normal force `sn = n . (f0 - K dx)` moves by at most `|K| |dx|`, the drag
///   (tangential spring and damping) by at most `|K| |dx| + |D| |dv|` before its cap `c sn` (a projection
///   onto a ball: 1-Lipschitz in the vector and in the radius), so `(2 + c) |K| |dx| + |D| |dv|`; the fade
///   weight moves by at most `1.5 / fade * |dx|` and multiplies a force of at most
///   `(1 + c) (|f0| + |K| (radius + |dx|))`;
/// - orthonormal planes: each plane's force is `k_j d_j + min(b_j approach_j, c k_j d_j)` along its own
///   normal with `d_j = max(0, offset_j - n_j . x)` (with orthonormal normals the projection onto the
///   constraint set is separable, so the proxy's multipliers equal the penalty depths), so at most
///   `(1 + c) k_max |dx| + b_max |dv|`.
fn lipschitz(model: Option<&LocalModel>, dx_mm: f32) -> (f32, f32) {
    let Some(m) = model else {
        return (0.0, 0.0);
    };
    let c = MAX_DRAG_PER_NORMAL;
    let k = psd_norm_bound(&m.stiffness_n_per_mm);
    let d = psd_norm_bound(&m.damping_n_s_per_mm);
    let (mut per_mm, mut per_mm_s) = (0.0, 0.0);
    if m.in_contact && m.attached {
        // Bilateral: `w (f0 - K dx - D v)`, no cap; the fade multiplies all of it, damping at the walk's
        // top speed included.
        per_mm += k + 1.5 / m.fade_mm
            * (norm(m.f0_n) + k * (m.radius_mm + dx_mm) + d * 1.1 * MAX_WALK_SPEED_MM_S);
        per_mm_s += d;
    } else if m.in_contact {
        let linear_per_mm = (2.0 + c) * k
            + 1.5 / m.fade_mm * (1.0 + c) * (norm(m.f0_n) + k * (m.radius_mm + dx_mm));
        per_mm += linear_per_mm;
        per_mm_s += d;
        // Friction about the stick point: `k_t |dx| + mu |dN|`, the normal force moving at most as the
        // linear part does.
        if m.friction_coefficient > 0.0 && m.stick_stiffness_n_per_mm > 0.0 {
            per_mm += m.stick_stiffness_n_per_mm + m.friction_coefficient * linear_per_mm;
            per_mm_s += m.friction_coefficient * d;
        }
    }
    // The drag of cutting, `-F v / sqrt(|v|^2 + v_s^2)`: its slope in v is at most F / v_s.
    per_mm_s += m.cut_drag_n / sinew_protocol::CUT_DRAG_SMOOTHING_MM_S;
    let planes = m.active_planes();
    let k_max = planes
        .iter()
        .map(|p| p.stiffness_n_per_mm)
        .fold(0.0, f32::max);
    let b_max = planes
        .iter()
        .map(|p| p.damping_n_s_per_mm)
        .fold(0.0, f32::max);
    (per_mm + (1.0 + c) * k_max, per_mm_s + b_max)
}

#[test]
fn random_models_and_motion_render_finite_and_lipschitz_forces() {
    // Per tick, with `M` and `O0` the model and the blend's starting offset in force after the previous
    // tick (a swap on this tick is evaluated so that this tick still renders M plus its offset):
    //   |F_t - F_{t-1}| <= L_x(M) |dx| + L_v(M) |dv| + |O0| dt / blend_s + float slack,
    // the decay term (the offset falls linearly) only while that blend runs (see `lipschitz` for L).
    let mut rng = fastrand::Rng::with_seed(0x5EED_F0CE);
    let config = RenderConfig::default();
    let mut renderer = ModelRenderer::try_new(config).unwrap();
    let mut walk = Walk {
        position_mm: [0.0; 3],
        velocity_mm_s: [0.0; 3],
    };
    let mut frame = random_frame(&mut rng);
    let mut model_in_force: Option<LocalModel> = None;
    let mut offset0_n = 0.0f32;
    let mut blend_start_s = f64::NEG_INFINITY;
    let mut previous_f = [0.0f32; 3];
    let mut previous_v = walk.velocity_mm_s;
    let mut previous_x = walk.position_mm;
    let mut burst_left = 0u32;
    let (mut swaps, mut nonzero_ticks) = (0u32, 0u32);
    // Largest step / bound on ticks without a running blend: how tight the Lipschitz part is.
    let mut worst_lipschitz_ratio = 0.0f32;
    for tick in 0..100_000u32 {
        let now_s = f64::from(tick) * DT_S;
        walk.step(&mut rng);
        let (x, v) = (walk.position_mm, walk.velocity_mm_s);
        let cleared = rng.f32() < 0.001;
        if cleared {
            renderer.clear();
            model_in_force = None;
            offset0_n = 0.0;
        }
        if burst_left == 0 && rng.f32() < 0.002 {
            burst_left = rng.u32(5..40);
        }
        let arrives = burst_left > 0 || rng.f32() < 0.03;
        burst_left = burst_left.saturating_sub(1);
        let bound_model = model_in_force;
        let bound_offset0_n = offset0_n;
        let bound_blend_start_s = blend_start_s;
        if arrives {
            if rng.f32() < 0.05 {
                frame = random_frame(&mut rng);
            }
            let model = random_model(&mut rng, x, &frame);
            renderer.accept(&model, now_s, x, v);
            model_in_force = Some(model);
            offset0_n = norm(renderer.blend_offset_n(now_s));
            blend_start_s = now_s;
            swaps += 1;
        }
        let f = renderer.force_n(now_s, x, v);
        assert!(all_finite(f), "tick {tick}: {f:?}");
        if tick > 0 && !cleared {
            let dx_mm = norm(sub(x, previous_x));
            let dv_mm_s = norm(sub(v, previous_v));
            let (l_x, l_v) = lipschitz(bound_model.as_ref(), dx_mm);
            let blending = now_s - DT_S - bound_blend_start_s < f64::from(config.blend_s);
            let decay_n = if blending {
                bound_offset0_n * (DT_S as f32) / config.blend_s
            } else {
                0.0
            };
            let slack_n = 1e-4 + 1e-5 * (norm(f) + norm(previous_f));
            // The cutting drag's texture: its level rises by at most dt / CUT_RISE_S a tick at a facet and
            // decays by at most dt / CUT_DRAG_TAU_S between.
            let texture_n = bound_model
                .filter(|m| m.cut_facet_mm > 0.0)
                .map_or(0.0, |m| {
                    m.cut_drag_n
                        * (DT_S as f32)
                        * (1.0 / super::super::cut_texture::CUT_RISE_S
                            + 1.0 / sinew_protocol::CUT_DRAG_TAU_S)
                });
            let bound_n = l_x * dx_mm + l_v * dv_mm_s + decay_n + texture_n + slack_n;
            let step_n = norm(sub(f, previous_f));
            assert!(
                step_n <= bound_n,
                "tick {tick}: step {step_n} N > bound {bound_n} N (dx {dx_mm} mm, dv {dv_mm_s} \
                 mm/s, decay {decay_n} N, model {bound_model:?})"
            );
            if !blending {
                worst_lipschitz_ratio = worst_lipschitz_ratio.max(step_n / bound_n);
            }
        }
        if norm(f) > 0.1 {
            nonzero_ticks += 1;
        }
        previous_f = f;
        previous_x = x;
        previous_v = v;
    }
    // The run exercised what it claims: many swaps, mostly in contact, and a bound that is not slack
    // everywhere (the worst tick uses a good part of it).
    assert!(swaps > 5_000, "{swaps} swaps");
    assert!(nonzero_ticks > 30_000, "{nonzero_ticks} ticks with force");
    assert!(
        worst_lipschitz_ratio > 0.2,
        "worst step/bound {worst_lipschitz_ratio}"
    );
}

#[test]
fn random_general_planes_keep_the_proxy_invariants() {
    // Planes in general position (any angles, up to four): the output is finite; the proxy stays clear of
    // every plane the previous proxy was clear of; and it is never farther from the device than the
    // previous proxy (which was a clear candidate).
    let mut rng = fastrand::Rng::with_seed(0xC0FFEE);
    let mut renderer = renderer();
    let mut walk = Walk {
        position_mm: [0.0; 3],
        velocity_mm_s: [0.0; 3],
    };
    let mut constrained_ticks = 0u32;
    for tick in 0..50_000u32 {
        let now_s = f64::from(tick) * DT_S;
        walk.step(&mut rng);
        let (x, v) = (walk.position_mm, walk.velocity_mm_s);
        if tick % 200 == 0 {
            let normals: [[f32; 3]; MAX_CONTACT_PLANES] =
                std::array::from_fn(|_| random_unit(&mut rng));
            let model = random_model(&mut rng, x, &normals);
            renderer.accept(&model, now_s, x, v);
        }
        let previous_proxy = renderer.proxy_position_mm();
        let f = renderer.force_n(now_s, x, v);
        assert!(all_finite(f), "tick {tick}: {f:?}");
        let (Some(before), Some(after), Some(model)) = (
            previous_proxy,
            renderer.proxy_position_mm(),
            renderer.model(),
        ) else {
            continue;
        };
        for plane in model.active_planes() {
            if dot3(plane.normal, before) >= plane.offset_mm - 1e-4 {
                let clearance_mm = dot3(plane.normal, after) - plane.offset_mm;
                assert!(
                    clearance_mm >= -1e-3,
                    "tick {tick}: proxy {clearance_mm} mm behind"
                );
                if dot3(plane.normal, x) < plane.offset_mm {
                    constrained_ticks += 1;
                }
            }
        }
        assert!(
            norm(sub(after, x)) <= norm(sub(before, x)) + 1e-3,
            "tick {tick}: proxy moved away from the device"
        );
    }
    assert!(
        constrained_ticks > 5_000,
        "{constrained_ticks} constrained plane-ticks"
    );
}

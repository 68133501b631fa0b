//! The renderer of the newest local model, and the blend that keeps its force continuous across model swaps.
//!
//! Owns: [`ModelRenderer`] (the model in use, its [`PlaneProxy`] and the blend offset) and its
//! [`RenderConfig`]. When a model arrives, the renderer evaluates both the force it renders now and the new
//! model's force at the same device state, and carries the difference as an offset that decays linearly to zero
//! over [`RenderConfig::blend_s`] (VRPN shifts a new plane so the penetration is unchanged and interpolates over
//! about ten servo ticks; this is the same idea applied to the whole force). A model arriving mid-blend starts
//! from the force rendered at that moment, so the force stays continuous however fast models arrive.
//!
//! Must not: decide when a model is stale (the loop calls [`ModelRenderer::clear`]), clamp or rate-limit
//! ([`crate::safety`]), read the clock (time is passed in), allocate, or panic.

use sinew_protocol::LocalModel;
use thiserror::Error;

use super::all_finite;
use super::local_model::linear_force_n;
use super::plane_proxy::PlaneProxy;

/// A [`RenderConfig`] value out of its domain.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("render config {field} = {value} is invalid: {reason}")]
pub struct RenderConfigError {
    /// The field.
    pub field: &'static str,
    /// The value given.
    pub value: f64,
    /// Why.
    pub reason: &'static str,
}

/// Settings of a [`ModelRenderer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderConfig {
    /// Time over which the force difference at a model swap is blended out, s (0 = swap at once).
    pub blend_s: f32,
}

impl RenderConfig {
    /// Default blend time, s: 15 ticks at 1 kHz.
    pub const DEFAULT_BLEND_S: f32 = 0.015;
    /// Longest blend time accepted, s.
    pub const MAX_BLEND_S: f32 = 0.1;

    /// Check every field.
    pub fn validate(&self) -> Result<(), RenderConfigError> {
        if !(self.blend_s.is_finite() && (0.0..=Self::MAX_BLEND_S).contains(&self.blend_s)) {
            return Err(RenderConfigError {
                field: "blend_s",
                value: f64::from(self.blend_s),
                reason: "must be finite, between 0 and 0.1 s",
            });
        }
        Ok(())
    }
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            blend_s: Self::DEFAULT_BLEND_S,
        }
    }
}

/// The offset added to the model's force, decaying linearly from `offset_n` at `start_s` to zero.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct ForceBlend {
    offset_n: [f32; 3],
    start_s: f64,
    /// Zero was rendered last (non-finite input): the next finite tick blends in from zero.
    from_zero_next: bool,
}

impl ForceBlend {
    const FROM_ZERO_NEXT: Self = Self {
        offset_n: [0.0; 3],
        start_s: 0.0,
        from_zero_next: true,
    };

    fn offset_at(&self, now_s: f64, blend_s: f32) -> [f32; 3] {
        if blend_s <= 0.0 {
            return [0.0; 3];
        }
        // A clock that steps back holds the offset (weight clamped to 1).
        let weight = (1.0 - (now_s - self.start_s) / f64::from(blend_s)).clamp(0.0, 1.0) as f32;
        self.offset_n.map(|c| weight * c)
    }
}

fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|i| a[i] + b[i])
}

/// The force of `model` at the device state: linear part plus planes, the latter moving `proxy`.
fn model_force_n(
    model: &LocalModel,
    proxy: &mut PlaneProxy,
    position_mm: [f32; 3],
    velocity_mm_s: [f32; 3],
) -> [f32; 3] {
    let linear_n = linear_force_n(model, position_mm, velocity_mm_s);
    let planes_n = proxy.step(model.active_planes(), position_mm, velocity_mm_s);
    add3(linear_n, planes_n)
}

/// Renders the newest local model against the current device state every tick, continuously across swaps.
///
/// Call [`ModelRenderer::accept`] when a model arrives and [`ModelRenderer::force_n`] every tick, with the same
/// device reading in both on a tick that has both (the swap is then exactly continuous).
#[derive(Debug, Clone)]
pub struct ModelRenderer {
    config: RenderConfig,
    model: Option<LocalModel>,
    proxy: PlaneProxy,
    blend: ForceBlend,
}

impl Default for ModelRenderer {
    fn default() -> Self {
        Self {
            config: RenderConfig::default(),
            model: None,
            proxy: PlaneProxy::new(),
            blend: ForceBlend::default(),
        }
    }
}

impl ModelRenderer {
    /// A renderer without a model (it renders zero). A `config` out of its domain is made valid, never used as
    /// is: a non-finite `blend_s` becomes the default, others are clamped to `0..=MAX_BLEND_S` (use
    /// [`ModelRenderer::try_new`] to refuse it instead, e.g. for a value from the command line).
    pub fn new(config: RenderConfig) -> Self {
        let blend_s = if config.blend_s.is_finite() {
            config.blend_s.clamp(0.0, RenderConfig::MAX_BLEND_S)
        } else {
            RenderConfig::DEFAULT_BLEND_S
        };
        Self {
            config: RenderConfig { blend_s },
            ..Self::default()
        }
    }

    /// A renderer without a model, or the reason `config` is out of its domain.
    pub fn try_new(config: RenderConfig) -> Result<Self, RenderConfigError> {
        config.validate()?;
        Ok(Self::new(config))
    }

    /// The settings.
    pub fn config(&self) -> RenderConfig {
        self.config
    }

    /// Whether a model is in use.
    pub fn has_model(&self) -> bool {
        self.model.is_some()
    }

    /// The model in use.
    pub fn model(&self) -> Option<&LocalModel> {
        self.model.as_ref()
    }

    /// The god-object proxy of the planes, mm, if there is one.
    pub fn proxy_position_mm(&self) -> Option<[f32; 3]> {
        self.proxy.position_mm()
    }

    /// The blend offset rendered on top of the model at `now_s`, N (zero once a blend is over).
    pub fn blend_offset_n(&self, now_s: f64) -> [f32; 3] {
        self.blend.offset_at(now_s, self.config.blend_s)
    }

    /// A new model arrived (validated by the decoder): render it from now on, continuously.
    ///
    /// With the device at `position_mm` moving at `velocity_mm_s`, the force rendered before the swap (old
    /// model plus its current offset; zero without a model) and the new model's force are evaluated at the
    /// same state; their difference becomes the offset, decaying to zero over [`RenderConfig::blend_s`]. The
    /// proxy is kept. Non-finite input: the model is taken, the proxy reset, and the next finite tick blends
    /// in from zero.
    ///
    /// Real-time contract: no allocation, never blocks, never panics.
    pub fn accept(
        &mut self,
        model: &LocalModel,
        now_s: f64,
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) {
        if !(now_s.is_finite() && all_finite(position_mm) && all_finite(velocity_mm_s)) {
            self.model = Some(*model);
            self.proxy.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            return;
        }
        let before_n = match &self.model {
            Some(old) if !self.blend.from_zero_next => {
                let mut proxy = self.proxy;
                let old_n = model_force_n(old, &mut proxy, position_mm, velocity_mm_s);
                add3(old_n, self.blend.offset_at(now_s, self.config.blend_s))
            }
            _ => [0.0; 3],
        };
        self.model = Some(*model);
        let mut proxy = self.proxy;
        let after_n = model_force_n(model, &mut proxy, position_mm, velocity_mm_s);
        let offset_n: [f32; 3] = std::array::from_fn(|i| before_n[i] - after_n[i]);
        self.blend = if all_finite(offset_n) {
            ForceBlend {
                offset_n,
                start_s: now_s,
                from_zero_next: false,
            }
        } else {
            self.proxy.reset();
            ForceBlend::FROM_ZERO_NEXT
        };
    }

    /// The force to render this tick, N: the model's linear part, its planes through the proxy, and the
    /// decaying blend offset. Zero without a model.
    ///
    /// Real-time contract: no allocation, never blocks, never panics, never returns a non-finite value:
    /// non-finite input (or a model that evaluates to one) gives zero, resets the proxy, and the next finite
    /// tick blends in from zero. The model is kept.
    pub fn force_n(
        &mut self,
        now_s: f64,
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) -> [f32; 3] {
        const ZERO: [f32; 3] = [0.0; 3];
        if !(now_s.is_finite() && all_finite(position_mm) && all_finite(velocity_mm_s)) {
            self.proxy.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            return ZERO;
        }
        let Some(model) = &self.model else {
            return ZERO;
        };
        let model_n = model_force_n(model, &mut self.proxy, position_mm, velocity_mm_s);
        if self.blend.from_zero_next {
            self.blend = ForceBlend {
                offset_n: model_n.map(|c| -c),
                start_s: now_s,
                from_zero_next: false,
            };
        }
        let force_n = add3(model_n, self.blend.offset_at(now_s, self.config.blend_s));
        if all_finite(force_n) {
            force_n
        } else {
            self.proxy.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            ZERO
        }
    }

    /// Drop the model, the proxy and any blend (the model went stale, or shutdown): zero from now on, and the
    /// next model blends in from zero.
    pub fn clear(&mut self) {
        self.model = None;
        self.proxy.reset();
        self.blend = ForceBlend::default();
    }
}

#[cfg(test)]
mod tests {
    use sinew_protocol::messages::{ContactPlane, MAX_CONTACT_PLANES};

    use super::*;
    use crate::render::{MAX_DRAG_PER_NORMAL, dot3};

    const DT_S: f64 = 0.001;

    fn norm(v: [f32; 3]) -> f32 {
        dot3(v, v).sqrt()
    }

    fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|i| a[i] - b[i])
    }

    /// In contact at the origin pushing `f0_z_n` along +z, `K = 0.2 I` N/mm, radius 10 mm, fade 2 mm.
    fn model_pushing(f0_z_n: f32) -> LocalModel {
        LocalModel {
            in_contact: true,
            f0_n: [0.0, 0.0, f0_z_n],
            stiffness_n_per_mm: [0.2, 0.2, 0.2, 0.0, 0.0, 0.0],
            radius_mm: 10.0,
            fade_mm: 2.0,
            ..LocalModel::default()
        }
    }

    fn renderer() -> ModelRenderer {
        ModelRenderer::try_new(RenderConfig::default()).unwrap()
    }

    #[test]
    fn config_domain() {
        assert_eq!(RenderConfig::default().blend_s, 0.015);
        for ok in [0.0, 0.015, 0.1] {
            assert!(RenderConfig { blend_s: ok }.validate().is_ok(), "{ok}");
        }
        for bad in [f32::NAN, f32::INFINITY, -0.001, 0.1001, 1.0] {
            let err = ModelRenderer::try_new(RenderConfig { blend_s: bad }).unwrap_err();
            assert_eq!(err.field, "blend_s");
            // The infallible constructor makes it valid instead.
            let made_valid = ModelRenderer::new(RenderConfig { blend_s: bad }).config();
            assert!(made_valid.validate().is_ok(), "{bad}: {made_valid:?}");
        }
    }

    #[test]
    fn a_swap_blends_over_blend_s_and_then_renders_the_new_model() {
        // Pressing in at 1 mm/s: each model changes by 0.2 N/mm * 0.001 mm = 0.0002 N per tick.
        let a = model_pushing(1.0);
        let b = model_pushing(2.0);
        let v = [0.0, 0.0, -1.0];
        let position = |tick: u32| [0.0, 0.0, -0.001 * tick as f32];
        let mut renderer = renderer();
        renderer.accept(&a, 0.0, position(0), v);
        // A model arriving without a previous one blends in from zero.
        assert_eq!(renderer.force_n(0.0, position(0), v), [0.0; 3]);
        let mut previous = [0.0; 3];
        for tick in 1..100u32 {
            let now_s = f64::from(tick) * DT_S;
            previous = renderer.force_n(now_s, position(tick), v);
        }
        assert!((previous[2] - linear_force_n(&a, position(99), v)[2]).abs() < 1e-5);

        let swap_tick = 100u32;
        let mut max_step_n = 0.0f32;
        for tick in swap_tick..=swap_tick + 30 {
            let now_s = f64::from(tick) * DT_S;
            if tick == swap_tick {
                renderer.accept(&b, now_s, position(tick), v);
            }
            let f = renderer.force_n(now_s, position(tick), v);
            if tick == swap_tick {
                // The swap tick still renders the old model's force.
                let old = linear_force_n(&a, position(tick), v);
                assert!(norm(sub(f, old)) < 1e-5, "{f:?} vs {old:?}");
            }
            max_step_n = max_step_n.max(norm(sub(f, previous)));
            if tick >= swap_tick + 15 {
                // blend_s = 15 ticks: the new model exactly.
                let new = linear_force_n(&b, position(tick), v);
                assert!(norm(sub(f, new)) < 1e-5, "tick {tick}: {f:?} vs {new:?}");
            }
            previous = f;
        }
        // 1 N spread over 15 ticks, plus the model's own 0.0002 N per tick; a step swap would show 1 N.
        let bound_n = 1.0 / 15.0 + 0.0002 + 1e-5;
        assert!(max_step_n <= bound_n, "max step {max_step_n} N > {bound_n}");
        assert!(max_step_n >= 1.0 / 15.0 - 1e-3, "max step {max_step_n} N");
    }

    #[test]
    fn alternating_models_every_tick_stay_continuous() {
        let a = model_pushing(1.0);
        let b = model_pushing(2.0);
        let x = [0.0, 0.0, -1.0];
        let mut renderer = renderer();
        renderer.accept(&a, 0.0, x, [0.0; 3]);
        // Past the ramp-in from zero: model A alone (1.2 N).
        let mut previous = [0.0; 3];
        for tick in 0..50u32 {
            previous = renderer.force_n(f64::from(tick) * DT_S, x, [0.0; 3]);
        }
        assert!((previous[2] - 1.2).abs() < 1e-5, "{previous:?}");
        let mut max_step_n = 0.0f32;
        for tick in 50..2000u32 {
            let now_s = f64::from(tick) * DT_S;
            let model = if tick % 2 == 0 { &a } else { &b };
            renderer.accept(model, now_s, x, [0.0; 3]);
            let f = renderer.force_n(now_s, x, [0.0; 3]);
            max_step_n = max_step_n.max(norm(sub(f, previous)));
            // Never outside what the two models render here (1.2 N and 2.2 N along z).
            assert!(f[0] == 0.0 && f[1] == 0.0 && (-1e-5..=2.2 + 1e-5).contains(&f[2]));
            previous = f;
        }
        // The offset is at most the 1 N the models disagree by, and decays by 1/15 of itself per tick.
        assert!(max_step_n <= 1.0 / 15.0 + 1e-5, "max step {max_step_n} N");
        // It hovers between the two models.
        assert!(previous[2] > 1.2 && previous[2] < 2.2, "{previous:?}");
    }

    #[test]
    fn clear_drops_the_model_and_the_next_one_ramps_in() {
        let a = model_pushing(1.0);
        let x = [0.0, 0.0, -3.0];
        let mut renderer = renderer();
        renderer.accept(&a, 0.0, x, [0.0; 3]);
        assert!(renderer.has_model());
        for tick in 0..=20u32 {
            renderer.force_n(f64::from(tick) * DT_S, x, [0.0; 3]);
        }
        renderer.clear();
        assert!(!renderer.has_model() && renderer.model().is_none());
        assert_eq!(renderer.proxy_position_mm(), None);
        assert_eq!(renderer.force_n(0.021, x, [0.0; 3]), [0.0; 3]);
        renderer.accept(&a, 0.022, x, [0.0; 3]);
        assert_eq!(renderer.model(), Some(&a));
        // 1.6 N ramps in over 15 ticks.
        for step in 0..=15u32 {
            let now_s = 0.022 + f64::from(step) * DT_S;
            let f = renderer.force_n(now_s, x, [0.0; 3]);
            let expected = 1.6 * step as f32 / 15.0;
            assert!((f[2] - expected).abs() < 1e-4, "step {step}: {f:?}");
        }
    }

    #[test]
    fn non_finite_input_renders_zero_resets_and_ramps_back() {
        let floor = ContactPlane {
            normal: [0.0, 0.0, 1.0],
            offset_mm: 0.0,
            stiffness_n_per_mm: 0.5,
            damping_n_s_per_mm: 0.0,
        };
        let mut planes = [ContactPlane::default(); MAX_CONTACT_PLANES];
        planes[0] = floor;
        let model = LocalModel {
            planes,
            plane_count: 1,
            radius_mm: 10.0,
            fade_mm: 1.0,
            ..LocalModel::default()
        };
        let mut renderer = renderer();
        renderer.accept(&model, 0.0, [0.0, 0.0, 1.0], [0.0; 3]);
        for tick in 0..20u32 {
            renderer.force_n(f64::from(tick) * DT_S, [0.0, 0.0, 1.0], [0.0; 3]);
        }
        let f = renderer.force_n(0.020, [0.0, 0.0, -2.0], [0.0; 3]);
        assert!((f[2] - 1.0).abs() < 1e-5, "{f:?}");
        for bad in [
            (f64::NAN, [0.0, 0.0, -2.0], [0.0; 3]),
            (0.021, [0.0, f32::NAN, -2.0], [0.0; 3]),
            (0.021, [0.0, 0.0, -2.0], [f32::INFINITY, 0.0, 0.0]),
        ] {
            assert_eq!(renderer.force_n(bad.0, bad.1, bad.2), [0.0; 3]);
            assert_eq!(renderer.proxy_position_mm(), None);
            assert!(renderer.has_model());
        }
        // Back from zero: the first finite tick renders zero, then 1 N (penalty: the proxy restarted inside)
        // ramps in over 15 ticks.
        for step in 0..=15u32 {
            let now_s = 0.022 + f64::from(step) * DT_S;
            let f = renderer.force_n(now_s, [0.0, 0.0, -2.0], [0.0; 3]);
            assert!(
                (f[2] - step as f32 / 15.0).abs() < 1e-4,
                "step {step}: {f:?}"
            );
        }
    }

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
    fn random_model(
        rng: &mut fastrand::Rng,
        near_mm: [f32; 3],
        normals: &[[f32; 3]],
    ) -> LocalModel {
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
        };
        assert!(model.validate().is_ok(), "{model:?}");
        model
    }

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
            if speed > 300.0 {
                self.velocity_mm_s = self.velocity_mm_s.map(|c| c * 300.0 / speed);
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
        if m.in_contact {
            per_mm += (2.0 + c) * k
                + 1.5 / m.fade_mm * (1.0 + c) * (norm(m.f0_n) + k * (m.radius_mm + dx_mm));
            per_mm_s += d;
        }
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
                let bound_n = l_x * dx_mm + l_v * dv_mm_s + decay_n + slack_n;
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
}

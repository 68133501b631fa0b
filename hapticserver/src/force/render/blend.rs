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
//!
//! Its randomized property tests (random models, swaps and device motion against a Lipschitz bound; random
//! planes against the proxy's invariants) are in `property_tests`; the deterministic ones are here.

use sinew_protocol::LocalModel;
use thiserror::Error;

use super::all_finite;
use super::cut_texture::CutTexture;
use super::friction_stick::StickPoint;
use super::local_model::linear_force_n;
use super::plane_proxy::PlaneProxy;
use super::puncture_pop::PopLatch;

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

/// What a model's rendering keeps between ticks besides the model: the planes' proxy, the friction's stick
/// point and the cutting drag's texture.
#[derive(Debug, Clone, Copy)]
struct RenderState {
    proxy: PlaneProxy,
    stick: StickPoint,
    texture: CutTexture,
}

impl RenderState {
    fn reset(&mut self) {
        self.proxy.reset();
        self.stick.reset();
        self.texture.reset();
    }

    /// The force of `model` at `now_s` and the device state: linear part, friction (moving the stick point),
    /// planes (moving the proxy) and the drag of cutting (moving its texture).
    fn force_n(
        &mut self,
        model: &LocalModel,
        now_s: f64,
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) -> [f32; 3] {
        let linear_n = linear_force_n(model, position_mm, velocity_mm_s);
        let friction_n = self.stick.step(model, linear_n, position_mm);
        let planes_n = self
            .proxy
            .step(model.active_planes(), position_mm, velocity_mm_s);
        add3(
            add3(add3(linear_n, friction_n), planes_n),
            self.texture.step(model, now_s, position_mm, velocity_mm_s),
        )
    }
}

/// Renders the newest local model against the current device state every tick, continuously across swaps.
///
/// Call [`ModelRenderer::accept`] when a model arrives and [`ModelRenderer::force_n`] every tick, with the same
/// device reading in both on a tick that has both (the swap is then exactly continuous).
#[derive(Debug, Clone)]
pub struct ModelRenderer {
    config: RenderConfig,
    model: Option<LocalModel>,
    state: RenderState,
    blend: ForceBlend,
    /// A needle's puncture popped here ([`PopLatch`]).
    pop: PopLatch,
    /// The device's orientation at the latest reading, `[x, y, z, w]` (a needle's tip moves with the turn).
    orientation_xyzw: [f32; 4],
}

impl Default for ModelRenderer {
    fn default() -> Self {
        Self {
            config: RenderConfig::default(),
            model: None,
            state: RenderState {
                proxy: PlaneProxy::new(),
                stick: StickPoint::default(),
                texture: CutTexture::default(),
            },
            blend: ForceBlend::default(),
            pop: PopLatch::default(),
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
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
        self.state.proxy.position_mm()
    }

    /// The friction's stick point, mm, while the tool pushes on frictional tissue.
    pub fn stick_point_mm(&self) -> Option<[f32; 3]> {
        self.state.stick.anchor_mm()
    }

    /// The device's orientation now, a unit quaternion `[x, y, z, w]` (wire frame, as its pose reports it): a
    /// needle's tip pressing a surface moves with the device's turn ([`PunctureTerm::rolled_push_n`]). A
    /// non-finite one is ignored.
    ///
    /// [`PunctureTerm::rolled_push_n`]: sinew_protocol::PunctureTerm::rolled_push_n
    pub fn set_orientation(&mut self, orientation_xyzw: [f32; 4]) {
        if all_finite4(orientation_xyzw) {
            self.orientation_xyzw = orientation_xyzw;
        }
    }

    /// Needle punctures popped at this device ([`PopLatch`]).
    pub fn pops(&self) -> u32 {
        self.pop.pops()
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
    /// A model of a needle press this device has already popped is taken as it is after the puncture
    /// ([`PopLatch::view`]).
    ///
    /// Real-time contract: no allocation, never blocks, never panics.
    pub fn accept(
        &mut self,
        model: &LocalModel,
        now_s: f64,
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) {
        let model = &self.pop.view(model);
        if !(now_s.is_finite() && all_finite(position_mm) && all_finite(velocity_mm_s)) {
            self.model = Some(*model);
            self.state.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            return;
        }
        let before_n = match &self.model {
            Some(old) if !self.blend.from_zero_next => {
                let mut state = self.state;
                let old_n = state.force_n(old, now_s, position_mm, velocity_mm_s);
                add3(old_n, self.blend.offset_at(now_s, self.config.blend_s))
            }
            _ => [0.0; 3],
        };
        self.model = Some(*model);
        let mut state = self.state;
        let after_n = state.force_n(model, now_s, position_mm, velocity_mm_s);
        let offset_n: [f32; 3] = std::array::from_fn(|i| before_n[i] - after_n[i]);
        self.blend = if all_finite(offset_n) {
            ForceBlend {
                offset_n,
                start_s: now_s,
                from_zero_next: false,
            }
        } else {
            self.state.reset();
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
            self.state.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            return ZERO;
        }
        let Some(mut model) = self.model else {
            return ZERO;
        };
        // A needle's tip tenting a surface punctures here the tick the model's push back along the tip passes
        // the threshold: the model is the punctured one from now on, the step not blended (module doc of
        // `puncture_pop`).
        if model.puncture.is_active()
            && self.pop.watch(
                &model,
                linear_force_n(&model, position_mm, velocity_mm_s),
                model
                    .puncture
                    .rolled_push_n(&model.stiffness_n_per_mm, self.orientation_xyzw),
            )
        {
            model = self.pop.view(&model);
            self.model = Some(model);
        }
        let model_n = self
            .state
            .force_n(&model, now_s, position_mm, velocity_mm_s);
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
            self.state.reset();
            self.blend = ForceBlend::FROM_ZERO_NEXT;
            ZERO
        }
    }

    /// Drop the model, the proxy and any blend (the model went stale, or shutdown): zero from now on, and the
    /// next model blends in from zero.
    pub fn clear(&mut self) {
        self.model = None;
        self.state.reset();
        self.blend = ForceBlend::default();
    }
}

/// Every component finite.
fn all_finite4(v: [f32; 4]) -> bool {
    v.iter().all(|c| c.is_finite())
}

#[cfg(test)]
mod property_tests;

#[cfg(test)]
mod tests {
    use sinew_protocol::messages::{ContactPlane, MAX_CONTACT_PLANES};

    use super::*;
    use crate::render::dot3;

    pub(super) const DT_S: f64 = 0.001;

    pub(super) fn norm(v: [f32; 3]) -> f32 {
        dot3(v, v).sqrt()
    }

    pub(super) fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
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

    pub(super) fn renderer() -> ModelRenderer {
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

    /// A needle's tip pressing down -z into tissue that pushes back +z with 1 N/mm (bilateral: the pressed
    /// point is held), popping at 2.45 N into a needle free along z, held 0.3 N/mm across it, dragging 0.2 N.
    fn needle_pressing(press: u32, server_time_ns: u64) -> LocalModel {
        LocalModel {
            server_time_ns,
            in_contact: true,
            f0_n: [0.0, 0.0, 1.0],
            stiffness_n_per_mm: [0.3, 0.3, 1.0, 0.0, 0.0, 0.0],
            radius_mm: 10.0,
            fade_mm: 2.0,
            attached: true,
            puncture: sinew_protocol::PunctureTerm {
                press,
                pop_at_n: 2.45,
                tip_axis: [0.0, 0.0, -1.0],
                f0_after_n: [0.0, 0.0, 0.0],
                stiffness_after_n_per_mm: [0.3, 0.3, 0.0, 0.0, 0.0, 0.0],
                drag_after_n: 0.2,
                tip_lever_mm: [0.0, 0.0, -10.0],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
            ..LocalModel::default()
        }
    }

    #[test]
    fn a_needle_pops_the_tick_its_push_passes_the_threshold_and_later_models_of_the_press_stay_popped()
     {
        let mut renderer = renderer();
        renderer.accept(&needle_pressing(7, 0), 0.0, [0.0; 3], [0.0; 3]);
        // The hand drives the tip down 0.1 mm a tick (100 mm/s): the push back grows 0.1 N a tick and passes
        // 2.45 N between 1.4 and 1.5 mm.
        let mut popped_at = None;
        let mut felt = Vec::new();
        for tick in 0..30u32 {
            let z = -0.1 * tick as f32;
            let f = renderer.force_n(
                0.05 + f64::from(tick) * DT_S,
                [0.0, 0.0, z],
                [0.0, 0.0, -100.0],
            );
            felt.push(f[2]);
            if popped_at.is_none() && renderer.pops() == 1 {
                popped_at = Some(tick);
            }
        }
        let tick = popped_at.expect("no pop");
        assert_eq!(tick, 15, "{felt:?}");
        // Up to the pop the tissue pushes back; the tick it pops the hand feels the needle's drag alone (no
        // blend: the tissue gave way).
        assert!((felt[14] - 2.4).abs() < 1e-4, "{felt:?}");
        assert!((felt[15] - 0.2).abs() < 0.01, "{felt:?}");
        assert!(
            felt[15..].iter().all(|f| (f - 0.2).abs() < 0.01),
            "{felt:?}"
        );
        // A model of the same press the server built before its needle got there: rendered popped.
        renderer.accept(
            &needle_pressing(7, 100_000_000),
            0.080,
            [0.0, 0.0, -3.0],
            [0.0, 0.0, -100.0],
        );
        let f = renderer.force_n(0.1, [0.0, 0.0, -3.0], [0.0, 0.0, -100.0]);
        assert!((f[2] - 0.2).abs() < 0.01, "{f:?}");
        assert_eq!(renderer.pops(), 1);
        // Across the path the needle is held: a 1 mm push sideways meets 0.3 N.
        let f = renderer.force_n(0.2, [1.0, 0.0, -3.0], [0.0; 3]);
        assert!((f[0] + 0.3).abs() < 1e-3, "{f:?}");
    }
    /// A needle is driven by rolling its driver: a hand that holds still and turns drives the tip with the turn
    /// alone, and the device pops when that turn's push passes the threshold. The tip 10 mm along x from the
    /// tool's origin, turned 0.01 rad a tick about y, goes down 10 sin(a) mm: against 1 N/mm it pushes back
    /// 1 + 10 sin(a) N and passes 2.45 N between 0.14 and 0.15 rad. Without the turn's push it would never pop
    /// (the device's position does not move).
    #[test]
    fn a_needle_pops_on_the_devices_turn_alone() {
        let mut renderer = renderer();
        let model = LocalModel {
            puncture: sinew_protocol::PunctureTerm {
                tip_lever_mm: [10.0, 0.0, 0.0],
                ..needle_pressing(3, 0).puncture
            },
            ..needle_pressing(3, 0)
        };
        renderer.accept(&model, 0.0, [0.0; 3], [0.0; 3]);
        let mut popped_at = None;
        for tick in 0..30u32 {
            let a = 0.01 * tick as f32;
            renderer.set_orientation([0.0, (a / 2.0).sin(), 0.0, (a / 2.0).cos()]);
            renderer.force_n(0.05 + f64::from(tick) * DT_S, [0.0; 3], [0.0; 3]);
            if popped_at.is_none() && renderer.pops() == 1 {
                popped_at = Some(tick);
            }
        }
        assert_eq!(popped_at, Some(15));
        // A turn the other way lifts the tip: no pop.
        let mut renderer = self::renderer();
        renderer.accept(&model, 0.0, [0.0; 3], [0.0; 3]);
        for tick in 0..30u32 {
            let a = -0.01 * tick as f32;
            renderer.set_orientation([0.0, (a / 2.0).sin(), 0.0, (a / 2.0).cos()]);
            renderer.force_n(0.05 + f64::from(tick) * DT_S, [0.0; 3], [0.0; 3]);
        }
        assert_eq!(renderer.pops(), 0);
    }
}

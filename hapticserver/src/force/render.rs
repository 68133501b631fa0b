//! Latency-moderated rendering: the newest [`LocalModel`] evaluated at the current device position every tick.
//!
//! Owns: the evaluation of a local model, split into its linear part ([`local_model`]: `f0 - K (x - x0) - D v`,
//! one-sided along the contact normal and faded out towards its radius), the drag of cutting with the sawtooth
//! of the facets the device's own travel cuts ([`cut_texture`]), its friction
//! about a stick point the device keeps ([`friction_stick`]), a needle's puncture popped at the device the tick
//! its push passes the threshold ([`puncture_pop`]), its unilateral planes rendered through
//! a god-object proxy ([`plane_proxy`], after Zilles and Salisbury, 1995) and the renderer that keeps the force
//! continuous when models are swapped ([`blend`]: [`ModelRenderer`]).
//!
//! Continuity is the theme: for a fixed model the rendered force is a continuous (Lipschitz) function of the
//! device position and velocity; a new model never makes the force jump (the difference is blended out over
//! [`RenderConfig::blend_s`]). The fade replaces the hard zero at the model's radius (VRPN's force-field step),
//! and the drag cap ([`MAX_DRAG_PER_NORMAL`]) removes the steps a one-sided contact otherwise has at touch-down
//! and at release.
//!
//! Must not: clamp, rate-limit or ramp forces for staleness (that is [`crate::safety`]), account energy
//! ([`crate::passivity`]), read the clock (time is passed in), the network or the device (time, model and reading are passed in),
//! allocate, or panic.
//!
//! [`LocalModel`]: sinew_protocol::LocalModel

pub mod blend;
pub mod cut_texture;
pub mod friction_stick;
pub mod local_model;
pub mod plane_proxy;
pub mod puncture_pop;

pub use blend::{ModelRenderer, RenderConfig, RenderConfigError};
pub use cut_texture::CutTexture;
pub use friction_stick::StickPoint;
pub use local_model::linear_force_n;
pub use plane_proxy::PlaneProxy;
pub use puncture_pop::PopLatch;

/// The dissipative and tangential parts of a one-sided contact force are at most this multiple of its elastic
/// normal part (dimensionless).
///
/// A one-sided contact switches on and off where its elastic normal force crosses zero. Damping of the approach
/// speed, and the tangential spring of the linear model, would make the force jump there (by `D v` or by the
/// sideways spring force) unless they vanish with the normal force: the same reasoning as the Hunt-Crossley
/// contact model (1975), whose damping scales with the penetration. Capping them at this ratio of the elastic
/// normal force (a friction-cone-like bound) keeps the force continuous at touch-down and at release, keeps
/// damping from ever pulling (ratio <= 1), and rarely binds in firm contact: tissue friction coefficients are
/// well below 1.
pub const MAX_DRAG_PER_NORMAL: f32 = 1.0;

/// `a . b`
pub(crate) fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Whether every component is finite.
pub(crate) fn all_finite(v: [f32; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

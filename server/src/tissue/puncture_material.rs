//! What a material does against a suture needle.
//!
//! Owns: [`PunctureSpec`] (read by `interaction::suture`, given by a world's `[objects.material]`).

/// A material's answer to a needle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PunctureSpec {
    /// The force along the tip's direction that punctures the surface, N.
    pub force_n: f32,
    /// The tip punctures only within this angle of the surface's normal, rad.
    pub max_angle_rad: f32,
    /// Coulomb friction of the needle sliding through the tissue.
    pub needle_friction: f32,
    /// A thread pulling on the tissue at one of its holes harder than this tears the tissue there: the suture
    /// cuts through it toward the pull (`interaction::suture::hole_tear`), N. None: it never tears.
    pub suture_tear_n: Option<f32>,
}

impl PunctureSpec {
    /// Defaults: 2.5 N (iMSTK's examples use 2-3; skin-like materials 1-4 N for a 3-0 needle), 37 degrees
    /// (iMSTK's 0.8 cosine), friction 0.2 (needle-tissue coefficients are 0.12-0.34).
    pub const DEFAULT: PunctureSpec = PunctureSpec {
        force_n: 2.5,
        max_angle_rad: 37.0 * std::f32::consts::PI / 180.0,
        needle_friction: 0.2,
        suture_tear_n: None,
    };
}

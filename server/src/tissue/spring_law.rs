//! Spring laws: how an edge's tension depends on its stretch. Chosen per object in the world file.
//!
//! Every law is written as `tension_n(stretch_mm, rest_mm, k)` with `k` the small-strain stiffness (N/mm), so
//! one world-file stiffness means the same thing under every law, plus the tangent `d tension / d stretch`
//! that the implicit integrator, XPBD's compliance and the stability bounds need. Pure functions, branch-light,
//! inlined into the force kernels.

/// Largest exponent the exponential law evaluates; beyond it the law continues linearly with the tangent it
/// has there (a stiffening of e^8 ~ 2981x), so an overstretched edge never produces an infinite force.
const MAX_EXPONENT: f32 = 8.0;

/// The tension law of an object's springs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpringLaw {
    /// Hooke: `T = k s`.
    Linear,
    /// Stiffness `k` up to `|strain| = knee_strain`, then `stiffness_ratio * k` beyond it (both in tension and
    /// in compression; a ratio above 1 models collagen fibres straightening).
    PiecewiseLinear {
        /// Strain (stretch / rest length) at the knee.
        knee_strain: f32,
        /// Stiffness beyond the knee over stiffness below it.
        stiffness_ratio: f32,
    },
    /// Fung-like exponential stiffening: `T = k L / b (exp(b s / L) - 1)`: slope `k` at rest, `k e^(b strain)`
    /// when stretched, softer in compression.
    Exponential {
        /// `b`, dimensionless: tangent stiffness grows by `e^b` at 100% strain.
        stiffening: f32,
    },
}

impl SpringLaw {
    /// Tension along the edge (positive pulls the ends together), N.
    #[inline(always)]
    pub fn tension_n(&self, stretch_mm: f32, rest_mm: f32, k_n_per_mm: f32) -> f32 {
        match *self {
            SpringLaw::Linear => k_n_per_mm * stretch_mm,
            SpringLaw::PiecewiseLinear {
                knee_strain,
                stiffness_ratio,
            } => {
                let knee_mm = knee_strain * rest_mm;
                let beyond = stretch_mm - stretch_mm.clamp(-knee_mm, knee_mm);
                k_n_per_mm * (stretch_mm + (stiffness_ratio - 1.0) * beyond)
            }
            SpringLaw::Exponential { stiffening } => {
                let length_scale_mm = rest_mm.max(1e-6) / stiffening;
                let e = stretch_mm / length_scale_mm;
                if e <= MAX_EXPONENT {
                    k_n_per_mm * length_scale_mm * e.exp_m1()
                } else {
                    let top = MAX_EXPONENT.exp();
                    k_n_per_mm
                        * (length_scale_mm * (top - 1.0)
                            + top * (stretch_mm - MAX_EXPONENT * length_scale_mm))
                }
            }
        }
    }

    /// Elastic energy stored at this stretch (the integral of the tension), N mm (= mJ).
    #[inline(always)]
    pub fn energy_n_mm(&self, stretch_mm: f32, rest_mm: f32, k_n_per_mm: f32) -> f32 {
        match *self {
            SpringLaw::Linear => 0.5 * k_n_per_mm * stretch_mm * stretch_mm,
            SpringLaw::PiecewiseLinear {
                knee_strain,
                stiffness_ratio,
            } => {
                let knee_mm = knee_strain * rest_mm;
                let beyond = stretch_mm - stretch_mm.clamp(-knee_mm, knee_mm);
                0.5 * k_n_per_mm
                    * (stretch_mm * stretch_mm + (stiffness_ratio - 1.0) * beyond * beyond)
            }
            SpringLaw::Exponential { stiffening } => {
                let length_scale_mm = rest_mm.max(1e-6) / stiffening;
                let e = stretch_mm / length_scale_mm;
                let capped = e.min(MAX_EXPONENT);
                let within = k_n_per_mm
                    * length_scale_mm
                    * (length_scale_mm * capped.exp_m1() - capped * length_scale_mm);
                if e <= MAX_EXPONENT {
                    within
                } else {
                    let beyond = stretch_mm - MAX_EXPONENT * length_scale_mm;
                    let top = MAX_EXPONENT.exp();
                    within
                        + k_n_per_mm * length_scale_mm * (top - 1.0) * beyond
                        + 0.5 * k_n_per_mm * top * beyond * beyond
                }
            }
        }
    }

    /// Tangent stiffness `dT / ds` at this stretch, N/mm (never negative).
    #[inline(always)]
    pub fn tangent_n_per_mm(&self, stretch_mm: f32, rest_mm: f32, k_n_per_mm: f32) -> f32 {
        match *self {
            SpringLaw::Linear => k_n_per_mm,
            SpringLaw::PiecewiseLinear {
                knee_strain,
                stiffness_ratio,
            } => {
                if stretch_mm.abs() > knee_strain * rest_mm {
                    k_n_per_mm * stiffness_ratio
                } else {
                    k_n_per_mm
                }
            }
            SpringLaw::Exponential { stiffening } => {
                let e = stretch_mm * stiffening / rest_mm.max(1e-6);
                k_n_per_mm * e.min(MAX_EXPONENT).exp()
            }
        }
    }

    /// The largest tangent stiffness over strains in `[-max_strain, max_strain]`, as a multiple of `k`: what the
    /// stability bound of an explicit method must assume.
    pub fn stiffening_at(&self, max_strain: f32) -> f32 {
        match *self {
            SpringLaw::Linear => 1.0,
            SpringLaw::PiecewiseLinear {
                knee_strain,
                stiffness_ratio,
            } => {
                if max_strain > knee_strain {
                    stiffness_ratio.max(1.0)
                } else {
                    1.0
                }
            }
            SpringLaw::Exponential { stiffening } => {
                (stiffening * max_strain).min(MAX_EXPONENT).exp()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numeric_tangent(law: SpringLaw, s: f32) -> f32 {
        let h = 1e-3;
        (law.tension_n(s + h, 10.0, 0.5) - law.tension_n(s - h, 10.0, 0.5)) / (2.0 * h)
    }

    #[test]
    fn every_law_has_slope_k_at_rest_and_a_matching_tangent() {
        let laws = [
            SpringLaw::Linear,
            SpringLaw::PiecewiseLinear {
                knee_strain: 0.1,
                stiffness_ratio: 4.0,
            },
            SpringLaw::Exponential { stiffening: 5.0 },
        ];
        for law in laws {
            assert_eq!(law.tension_n(0.0, 10.0, 0.5), 0.0, "{law:?}");
            assert!((numeric_tangent(law, 0.0) - 0.5).abs() < 1e-3, "{law:?}");
            for s in [-2.0f32, -0.5, 0.3, 0.7, 3.0] {
                let analytic = law.tangent_n_per_mm(s, 10.0, 0.5);
                let numeric = numeric_tangent(law, s);
                assert!(
                    (analytic - numeric).abs() < 2e-2 * analytic,
                    "{law:?} at {s}: {analytic} vs {numeric}"
                );
            }
        }
    }

    #[test]
    fn energy_is_the_integral_of_tension() {
        let laws = [
            SpringLaw::Linear,
            SpringLaw::PiecewiseLinear {
                knee_strain: 0.1,
                stiffness_ratio: 4.0,
            },
            SpringLaw::Exponential { stiffening: 5.0 },
        ];
        for law in laws {
            for s in [-2.0f32, -0.5, 0.3, 0.7, 3.0] {
                let h = 1e-3;
                let numeric = (law.energy_n_mm(s + h, 10.0, 0.5)
                    - law.energy_n_mm(s - h, 10.0, 0.5))
                    / (2.0 * h);
                let tension = law.tension_n(s, 10.0, 0.5);
                assert!(
                    (numeric - tension).abs() < 1e-2 * tension.abs().max(0.1),
                    "{law:?} at {s}: {numeric} vs {tension}"
                );
            }
        }
    }

    #[test]
    fn piecewise_stiffens_past_the_knee_and_exponential_stiffens_in_tension() {
        let piecewise = SpringLaw::PiecewiseLinear {
            knee_strain: 0.1,
            stiffness_ratio: 4.0,
        };
        // 2 mm on a 10 mm edge: 1 mm at k, 1 mm at 4k.
        assert!((piecewise.tension_n(2.0, 10.0, 0.5) - 2.5).abs() < 1e-5);
        assert!((piecewise.tension_n(-2.0, 10.0, 0.5) + 2.5).abs() < 1e-5);
        let exponential = SpringLaw::Exponential { stiffening: 5.0 };
        assert!(exponential.tension_n(2.0, 10.0, 0.5) > 1.0 * 1.5);
        assert!(exponential.tension_n(-2.0, 10.0, 0.5).abs() < 1.0);
    }

    #[test]
    fn exponential_stays_finite_when_overstretched() {
        let law = SpringLaw::Exponential { stiffening: 20.0 };
        let t = law.tension_n(1e6, 1.0, 1.0);
        assert!(t.is_finite() && t > 0.0);
        assert!(law.tangent_n_per_mm(1e6, 1.0, 1.0).is_finite());
    }
}

//! A curved suture needle's geometry: a circular arc in the needle's own frame.
//!
//! Owns: [`NeedleArc`]. The needle frame: the arc's centre at the origin, the arc in the x-y plane, running
//! counter-clockwise about +z from the tail (angle 0, on +x, where the thread is swaged) to the sharp tip (angle
//! `sweep_rad`). A point on the needle is named by its angle `theta_rad` from the tail, or its arc length
//! `radius * theta` from the tail. The tip's direction is the arc's tangent there: a needle driven along its
//! own arc passes through the tissue along one path, which is what the path constraint holds it to.
//!
//! Pure and allocation-free: it runs on the sim tick.

use thiserror::Error;

use crate::tissue::Vec3;

/// Why a needle's arc cannot be built.
#[derive(Debug, Error, PartialEq)]
pub enum NeedleArcError {
    /// The radius is not a positive finite length.
    #[error("needle radius_mm must be positive and finite, got {0}")]
    Radius(f32),
    /// The sweep is not an angle strictly between 0 and a full turn.
    #[error("needle sweep_deg must be above 0 and below 360, got {0}")]
    Sweep(f32),
}

/// A circular needle: radius and sweep (iMSTK's default arc is 10.7 mm and about 116 degrees; a 3/8 circle,
/// the commonest skin needle, sweeps 135 degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleArc {
    radius_mm: f32,
    sweep_rad: f32,
}

/// A point on the arc: its angle from the tail, its position and its unit tangent toward the tip (needle
/// frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcPoint {
    /// Angle from the tail, rad, in `[0, sweep]`.
    pub theta_rad: f32,
    /// Position, mm.
    pub point_mm: Vec3,
    /// Unit tangent toward the tip.
    pub tangent: Vec3,
}

/// Where a point lies against the arc's path (needle frame): the nearest point on the arc, and the point's
/// offset from it split into the part along the tangent (beyond an end of the arc), the part in the arc's
/// plane across it (radial: outward positive) and the part out of the plane (along +z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOffset {
    /// The nearest point on the arc.
    pub nearest: ArcPoint,
    /// Offset along the tangent, mm (non-zero only past the tail or the tip).
    pub along_mm: f32,
    /// Offset in the arc's plane away from the centre, mm.
    pub radial_mm: f32,
    /// Offset out of the arc's plane, mm.
    pub out_of_plane_mm: f32,
}

impl PathOffset {
    /// Distance from the point to the arc's path, mm.
    pub fn distance_mm(&self) -> f32 {
        (self.along_mm * self.along_mm
            + self.radial_mm * self.radial_mm
            + self.out_of_plane_mm * self.out_of_plane_mm)
            .sqrt()
    }

    /// Distance across the path (the sideways deviation a path constraint resists), mm.
    pub fn across_mm(&self) -> f32 {
        self.radial_mm.hypot(self.out_of_plane_mm)
    }
}

impl NeedleArc {
    /// iMSTK's default needle: 10.7 mm radius, 116 degrees.
    pub const IMSTK_DEFAULT: NeedleArc = NeedleArc {
        radius_mm: 10.7,
        sweep_rad: 116.0 * std::f32::consts::PI / 180.0,
    };

    /// The arc of `radius_mm` sweeping `sweep_deg` degrees.
    pub fn new(radius_mm: f32, sweep_deg: f32) -> Result<Self, NeedleArcError> {
        if !(radius_mm.is_finite() && radius_mm > 0.0) {
            return Err(NeedleArcError::Radius(radius_mm));
        }
        if !(sweep_deg.is_finite() && sweep_deg > 0.0 && sweep_deg < 360.0) {
            return Err(NeedleArcError::Sweep(sweep_deg));
        }
        Ok(Self {
            radius_mm,
            sweep_rad: sweep_deg.to_radians(),
        })
    }

    /// Radius, mm.
    pub fn radius_mm(&self) -> f32 {
        self.radius_mm
    }

    /// Sweep, rad.
    pub fn sweep_rad(&self) -> f32 {
        self.sweep_rad
    }

    /// Length along the arc, tail to tip, mm.
    pub fn length_mm(&self) -> f32 {
        self.radius_mm * self.sweep_rad
    }

    /// The point at `theta_rad` from the tail (clamped to the arc).
    pub fn at(&self, theta_rad: f32) -> ArcPoint {
        let theta_rad = if theta_rad.is_nan() {
            0.0
        } else {
            theta_rad.clamp(0.0, self.sweep_rad)
        };
        let (sin, cos) = theta_rad.sin_cos();
        ArcPoint {
            theta_rad,
            point_mm: Vec3::new(cos, sin, 0.0) * self.radius_mm,
            tangent: Vec3::new(-sin, cos, 0.0),
        }
    }

    /// The sharp tip and the direction it points.
    pub fn tip(&self) -> ArcPoint {
        self.at(self.sweep_rad)
    }

    /// The tail, where the thread is swaged.
    pub fn tail(&self) -> ArcPoint {
        self.at(0.0)
    }

    /// Where `point_mm` lies against the arc's path (needle frame). A point on the axis (equidistant from the
    /// whole circle) is taken against the arc's middle. Never panics; a non-finite point gives a non-finite
    /// offset.
    pub fn offset_of(&self, point_mm: &Vec3) -> PathOffset {
        let planar = point_mm.xy();
        let rho = planar.norm();
        let theta = if rho > 1e-9 * self.radius_mm {
            let angle = planar.y.atan2(planar.x);
            // The arc spans [0, sweep]; an angle outside it belongs to the nearer end, measured around the
            // circle (an angle just below 0 is near the tail, not near a tip 360 degrees round).
            let angle = if angle < 0.0 {
                angle + std::f32::consts::TAU
            } else {
                angle
            };
            if angle <= self.sweep_rad {
                angle
            } else if angle - self.sweep_rad <= std::f32::consts::TAU - angle {
                self.sweep_rad
            } else {
                0.0
            }
        } else {
            0.5 * self.sweep_rad
        };
        let nearest = self.at(theta);
        let d = point_mm - nearest.point_mm;
        let radial_dir = nearest.point_mm / self.radius_mm;
        PathOffset {
            nearest,
            along_mm: d.dot(&nearest.tangent),
            radial_mm: d.dot(&radial_dir),
            out_of_plane_mm: d.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn imstk() -> NeedleArc {
        NeedleArc::new(10.7, 116.0).unwrap()
    }

    #[test]
    fn the_arc_runs_from_tail_to_tip_with_its_tangent_toward_the_tip() {
        let arc = imstk();
        assert!((arc.length_mm() - 10.7 * 116f32.to_radians()).abs() < 1e-4);
        let tail = arc.tail();
        assert!((tail.point_mm - Vec3::new(10.7, 0.0, 0.0)).norm() < 1e-5);
        assert!((tail.tangent - Vec3::y()).norm() < 1e-6);
        let tip = arc.tip();
        assert!((tip.point_mm.norm() - 10.7).abs() < 1e-4);
        assert!((tip.theta_rad - 116f32.to_radians()).abs() < 1e-6);
        // Everywhere: on the circle, tangent unit and across the radius, pointing the way theta grows.
        for k in 0..=20 {
            let p = arc.at(arc.sweep_rad() * k as f32 / 20.0);
            assert!((p.point_mm.norm() - 10.7).abs() < 1e-4 && p.point_mm.z == 0.0);
            assert!(
                (p.tangent.norm() - 1.0).abs() < 1e-6 && p.tangent.dot(&p.point_mm).abs() < 1e-4
            );
            let ahead = arc.at(p.theta_rad + 1e-3).point_mm - p.point_mm;
            assert!(k == 20 || ahead.dot(&p.tangent) > 0.0);
        }
        // Clamped to the arc; NaN is the tail.
        assert_eq!(arc.at(10.0), arc.tip());
        assert_eq!(arc.at(-1.0), arc.tail());
        assert_eq!(arc.at(f32::NAN), arc.tail());
    }

    #[test]
    fn a_point_is_measured_against_the_nearest_point_of_the_path() {
        let arc = imstk();
        let mid = arc.at(1.0);
        // On the arc: no offset.
        let on = arc.offset_of(&mid.point_mm);
        assert!((on.nearest.theta_rad - 1.0).abs() < 1e-5 && on.distance_mm() < 1e-4);
        // 2 mm out of the plane and 1 mm outward: split as such, along nothing.
        let radial = mid.point_mm / 10.7;
        let off = arc.offset_of(&(mid.point_mm + Vec3::z() * 2.0 + radial));
        assert!((off.out_of_plane_mm - 2.0).abs() < 1e-5 && (off.radial_mm - 1.0).abs() < 1e-5);
        assert!(off.along_mm.abs() < 1e-5 && (off.across_mm() - 5f32.sqrt()).abs() < 1e-5);
        // Past the tip along its tangent: the tip is nearest, the offset is along.
        let tip = arc.tip();
        let past = arc.offset_of(&(tip.point_mm + tip.tangent * 3.0));
        assert_eq!(past.nearest.theta_rad, tip.theta_rad);
        assert!((past.along_mm - 3.0).abs() < 1e-4 && past.radial_mm.abs() < 0.5);
        // Behind the tail (just below angle 0): the tail, not the tip 244 degrees round.
        let behind = arc.offset_of(&(arc.tail().point_mm - Vec3::y() * 2.0));
        assert_eq!(behind.nearest.theta_rad, 0.0);
        assert!((behind.along_mm + 2.0).abs() < 1e-4);
        // Opposite the gap, nearer the tip's side: the tip.
        let beyond_tip = arc.offset_of(&Vec3::new(
            (130f32.to_radians()).cos() * 10.7,
            (130f32.to_radians()).sin() * 10.7,
            0.0,
        ));
        assert_eq!(beyond_tip.nearest.theta_rad, arc.sweep_rad());
        // On the axis: the middle, all of it across. Non-finite in, non-finite out, no panic.
        let axis = arc.offset_of(&Vec3::new(0.0, 0.0, 1.0));
        assert!((axis.nearest.theta_rad - 0.5 * arc.sweep_rad()).abs() < 1e-6);
        assert!(
            !arc.offset_of(&Vec3::new(f32::NAN, 0.0, 0.0))
                .distance_mm()
                .is_finite()
        );
    }

    #[test]
    fn a_needle_that_is_not_an_arc_is_refused_with_its_key() {
        assert_eq!(NeedleArc::new(0.0, 116.0), Err(NeedleArcError::Radius(0.0)));
        assert!(NeedleArc::new(f32::NAN, 116.0).is_err());
        assert_eq!(
            NeedleArc::new(10.0, 360.0),
            Err(NeedleArcError::Sweep(360.0))
        );
        assert!(NeedleArc::new(10.0, 0.0).is_err());
        assert!(NeedleArc::new(10.0, f32::INFINITY).is_err());
        let message = NeedleArc::new(-1.0, 90.0).unwrap_err().to_string();
        assert!(message.contains("radius_mm"), "{message}");
        assert!(NeedleArc::new(10.0, 135.0).is_ok());
    }
}

//! Where a needle driver's needle lies in its tool's frame: the one map the server and the viewers share.
//!
//! Owns: [`needle_point_in_tool_mm`]. The needle's arc has its centre at `(0, radius, 0)` in the tool frame,
//! lies in the tool's x-y plane, and passes through the tool origin at the angle where the jaws hold it, its
//! tangent there along +x; a point `theta_rad` from the tail sits at angle `theta - grasp_at - pi/2` about
//! the centre (so the tip curves round toward +y). The server's `NeedleDriverSpec::tool_from_needle` is the
//! same map; a server test holds the two equal.

/// The point of a needle (arc `radius_mm`, held `grasp_at_rad` from its tail) at `theta_rad` from its tail,
/// in the tool frame, mm.
pub fn needle_point_in_tool_mm(radius_mm: f32, grasp_at_rad: f32, theta_rad: f32) -> [f32; 3] {
    let angle = theta_rad - grasp_at_rad - std::f32::consts::FRAC_PI_2;
    let (sin, cos) = angle.sin_cos();
    [radius_mm * cos, radius_mm + radius_mm * sin, 0.0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_held_point_is_the_tool_origin_and_the_tip_curves_toward_plus_y() {
        let held = needle_point_in_tool_mm(10.0, 0.7, 0.7);
        assert!(held.iter().all(|c| c.abs() < 1e-5), "{held:?}");
        let ahead = needle_point_in_tool_mm(10.0, 0.7, 0.8);
        assert!(ahead[0] > 0.9 && ahead[1] > 0.0, "{ahead:?}");
    }
}

//! Where the camera looks from, given what the replica holds.
//!
//! Owns: the framing rule (look at the centre of everything drawn, from above and in front, z up, far enough
//! that the bounding sphere fits the field of view). Must not: touch kiss3d or the GPU; it is plain math so
//! it is tested without a display.

use crate::replica::SceneReplica;

/// Vertical field of view, radians (kiss3d's default, 45 degrees).
pub const FIELD_OF_VIEW_RAD: f32 = std::f32::consts::FRAC_PI_4;

/// Extent framed when the replica holds nothing to draw: the pad's 80 x 60 mm around the origin.
const EMPTY_SCENE_MIN_MM: [f32; 3] = [-40.0, -30.0, 0.0];
const EMPTY_SCENE_MAX_MM: [f32; 3] = [40.0, 30.0, 0.0];

/// A camera placement in world millimetres (z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFraming {
    /// Camera position, mm.
    pub eye_mm: [f32; 3],
    /// Point looked at, mm.
    pub target_mm: [f32; 3],
    /// Near clip distance, mm.
    pub znear_mm: f32,
    /// Far clip distance, mm.
    pub zfar_mm: f32,
}

/// Axis-aligned box around every object vertex and tool (tools padded by their radius); the pad's extent if
/// there is nothing.
pub fn scene_bounds_mm(replica: &SceneReplica) -> ([f32; 3], [f32; 3]) {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    let mut grow = |p: [f32; 3], pad: f32| {
        for a in 0..3 {
            if p[a].is_finite() {
                min[a] = min[a].min(p[a] - pad);
                max[a] = max[a].max(p[a] + pad);
            }
        }
    };
    for object in replica.objects() {
        for p in object.positions_mm_iter() {
            grow(p, 0.0);
        }
    }
    for state in &replica.tool_states().tools {
        let radius = replica
            .tools()
            .iter()
            .find(|t| t.tool == state.tool)
            .map_or(0.0, |t| t.shape.bounding_radius_mm());
        grow(state.position_mm, radius);
    }
    if (0..3).any(|a| min[a] > max[a]) {
        return (EMPTY_SCENE_MIN_MM, EMPTY_SCENE_MAX_MM);
    }
    (min, max)
}

/// Frame the box `min_mm..max_mm`: look at its centre from above and in front (-y), at a distance where its
/// bounding sphere fits the vertical field of view.
pub fn frame_box(min_mm: [f32; 3], max_mm: [f32; 3]) -> CameraFraming {
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (min_mm[a] + max_mm[a]));
    let radius = 0.5
        * (0..3)
            .map(|a| (max_mm[a] - min_mm[a]).powi(2))
            .sum::<f32>()
            .sqrt();
    let radius = radius.max(5.0);
    // The bounding sphere just fits; flat scenes seen at an angle look small at that distance, so come closer.
    let distance = 0.85 * radius / (0.5 * FIELD_OF_VIEW_RAD).sin();
    // In front (-y) and above (+z), about 50 degrees down.
    let direction = [0.0, -0.64, 0.77];
    let eye_mm = std::array::from_fn(|a| centre[a] + direction[a] * distance);
    CameraFraming {
        eye_mm,
        target_mm: centre,
        znear_mm: (distance - 2.0 * radius).max(distance * 0.01),
        zfar_mm: distance + 4.0 * radius,
    }
}

/// Frame everything the replica holds.
pub fn frame_replica(replica: &SceneReplica) -> CameraFraming {
    let (min, max) = scene_bounds_mm(replica);
    frame_box(min, max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_replica_frames_the_pad_from_above_and_in_front() {
        let framing = frame_replica(&SceneReplica::new());
        assert_eq!(framing.target_mm, [0.0, 0.0, 0.0]);
        assert!(framing.eye_mm[2] > 50.0, "{framing:?}");
        assert!(framing.eye_mm[1] < -50.0, "{framing:?}");
        let distance = framing.eye_mm.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!(framing.znear_mm < distance - 50.0 && framing.zfar_mm > distance + 50.0);
        assert!(framing.znear_mm > 0.0);
    }

    #[test]
    fn degenerate_box_still_gets_a_usable_distance() {
        let framing = frame_box([1.0; 3], [1.0; 3]);
        assert!(framing.znear_mm > 0.0 && framing.zfar_mm > framing.znear_mm);
        assert_ne!(framing.eye_mm, framing.target_mm);
    }
}

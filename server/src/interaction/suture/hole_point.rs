//! Where a hole or a ring holds the thread in the tissue: a material point of the surface or of the volume.
//!
//! Owns: [`HolePoint`] (which of the two, where it is now, and how a force on it is spread on the tissue's nodes
//! by their weights). `thread_hole.rs` holds the thread there.
//!
//! Must not: panic on a point whose element is gone (it has no place and spreads nothing).

use super::SurfacePoint;
use super::volume_point::VolumePoint;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// Where a ring holds the thread: a hole in the surface, or a point of the needle's track inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HolePoint {
    /// A puncture hole: the thread crosses the surface there.
    Surface(SurfacePoint),
    /// A point of the needle's track inside the volume.
    Volume(VolumePoint),
}

impl HolePoint {
    /// The object it is in.
    pub fn object(&self) -> u16 {
        match self {
            HolePoint::Surface(p) => p.object,
            HolePoint::Volume(p) => p.object,
        }
    }

    /// The same point after object `object` was subdivided (see [`SurfacePoint::remapped`]).
    pub fn remapped(
        &self,
        object: usize,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) -> Self {
        match self {
            HolePoint::Surface(p) => HolePoint::Surface(p.remapped(object, remap)),
            HolePoint::Volume(p) => HolePoint::Volume(p.remapped(object, remap)),
        }
    }

    /// A hole in the surface (not a point of a track inside).
    pub fn is_surface(&self) -> bool {
        matches!(self, HolePoint::Surface(_))
    }

    /// Where it is now, mm (None: its triangle or tetrahedron is gone).
    pub fn position_mm(&self, model: &MassSpringModel, state: &TissueState) -> Option<Vec3> {
        match self {
            HolePoint::Surface(p) => p.position_mm(model, state),
            HolePoint::Volume(p) => p.position_mm(model, state),
        }
    }

    /// Spread `force_n` on the nodes carrying it, by their weights, into `forces_n` (a corner out of range is
    /// skipped; a point whose element is gone spreads nothing).
    pub fn spread(&self, model: &MassSpringModel, force_n: &Vec3, forces_n: &mut [Vec3]) {
        // The corners and their weights: a triangle's three, or a tetrahedron's four.
        let (corners, weights): ([u32; 4], [f32; 4]) = match self {
            HolePoint::Surface(p) => match p.corners(model) {
                Some([a, b, c]) => (
                    [a, b, c, 0],
                    [p.barycentric[0], p.barycentric[1], p.barycentric[2], 0.0],
                ),
                None => return,
            },
            HolePoint::Volume(p) => match p.corners(model) {
                Some(corners) => (corners, p.barycentric),
                None => return,
            },
        };
        for (&c, &b) in corners.iter().zip(&weights).filter(|(_, b)| **b != 0.0) {
            if let Some(f) = forces_n.get_mut(c as usize) {
                *f += force_n * b;
            }
        }
    }
}

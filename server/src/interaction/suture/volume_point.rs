//! A material point inside an object's volume: a tetrahedron (its index) and the weights of its four corners.
//!
//! Owns: [`VolumePoint`] (where it is now, which nodes carry it) and [`VolumePoint::locate`] (the material point
//! at a place inside the tissue as it is now). The thread's tracks are made of these (`thread_hole.rs`): where
//! the needle's tail has passed through the tissue, the tissue holds the thread on the needle's path, not only
//! at the two holes in its surface.
//!
//! Must not: allocate or panic; a tetrahedron the model no longer has, or a non-finite place, reads as None.

use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A place this far outside the nearest tetrahedron (in its weights) still counts as inside it.
const OUTSIDE_WEIGHT: f32 = 0.05;

/// A material point of an object's volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumePoint {
    /// Object index in the world.
    pub object: u16,
    /// Tetrahedron of the object's volume terms (`MassSpringModel::tets`).
    pub tet: u32,
    /// Weights of the tetrahedron's corners (sum 1).
    pub barycentric: [f32; 4],
}

impl VolumePoint {
    /// The same material point after object `object` was subdivided: in the piece of its tetrahedron that holds
    /// it ([`ElementRemap::tet`]); unchanged in another object.
    pub fn remapped(
        &self,
        object: usize,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) -> Self {
        if usize::from(self.object) != object {
            return *self;
        }
        let (tet, barycentric) = remap.tet(self.tet, self.barycentric);
        Self {
            tet,
            barycentric,
            ..*self
        }
    }

    /// The material point of object `object` at `place_mm` in the tissue as it is now: the tetrahedron holding
    /// it (or the nearest, within a twentieth of its size outside), its weights clamped to it. None when no
    /// tetrahedron holds it, the object has none, or the place is not finite. Scans every tetrahedron: for an
    /// event (the needle's tail passing), not a substep.
    pub fn locate(
        object: u16,
        model: &MassSpringModel,
        state: &TissueState,
        place_mm: &Vec3,
    ) -> Option<Self> {
        if !place_mm.iter().all(|c| c.is_finite()) {
            return None;
        }
        let x = &state.positions_mm;
        let mut best: Option<(f32, u32, [f32; 4])> = None;
        for (k, tet) in model.tets().tets.iter().enumerate() {
            let corners = tet.map(|i| x.get(i as usize).copied());
            let [Some(a), Some(b), Some(c), Some(d)] = corners else {
                continue;
            };
            let Some(w) = weights(&a, &b, &c, &d, place_mm) else {
                continue;
            };
            let worst = w.iter().fold(f32::INFINITY, |m, &v| m.min(v));
            if best.is_none_or(|(m, _, _)| worst > m) {
                best = Some((worst, k as u32, w));
            }
        }
        let (_, tet, w) = best.filter(|(m, _, _)| *m >= -OUTSIDE_WEIGHT)?;
        let clamped = w.map(|v| v.max(0.0));
        let sum: f32 = clamped.iter().sum();
        Some(Self {
            object,
            tet,
            barycentric: clamped.map(|v| v / sum),
        })
    }

    /// The tetrahedron's corners, if the model has it.
    pub fn corners(&self, model: &MassSpringModel) -> Option<[u32; 4]> {
        model.tets().tets.get(self.tet as usize).copied()
    }

    /// Where the point is now, mm.
    pub fn position_mm(&self, model: &MassSpringModel, state: &TissueState) -> Option<Vec3> {
        let corners = self.corners(model)?;
        let mut sum = Vec3::zeros();
        for (&c, &b) in corners.iter().zip(&self.barycentric) {
            sum += state.positions_mm.get(c as usize)? * b;
        }
        Some(sum)
    }
}

/// The weights of `p` in the tetrahedron `a b c d` (None: degenerate).
fn weights(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3, p: &Vec3) -> Option<[f32; 4]> {
    let (e1, e2, e3, r) = (b - a, c - a, d - a, p - a);
    let volume = e1.dot(&e2.cross(&e3));
    if volume.is_nan() || volume.abs() <= 1e-9 {
        return None;
    }
    let wb = r.dot(&e2.cross(&e3)) / volume;
    let wc = e1.dot(&r.cross(&e3)) / volume;
    let wd = e1.dot(&e2.cross(&r)) / volume;
    Some([1.0 - wb - wc - wd, wb, wc, wd])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_weights_of_a_tetrahedrons_corners_and_centre_are_exact() {
        let [a, b, c, d] = [
            Vec3::zeros(),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 2.0),
        ];
        assert_eq!(weights(&a, &b, &c, &d, &b), Some([0.0, 1.0, 0.0, 0.0]));
        let centre = (a + b + c + d) / 4.0;
        let w = weights(&a, &b, &c, &d, &centre).unwrap();
        assert!(w.iter().all(|v| (v - 0.25).abs() < 1e-6), "{w:?}");
        let outside = weights(&a, &b, &c, &d, &Vec3::new(-1.0, 0.5, 0.5)).unwrap();
        assert!(outside[1] < 0.0, "{outside:?}");
        assert_eq!(weights(&a, &b, &b, &d, &centre), None);
    }
}

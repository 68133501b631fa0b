//! The single conversion point between the simulation's nalgebra types and parry3d's glam types.

use nalgebra::{UnitQuaternion, Vector3};
use parry3d::glamx::Quat;
use parry3d::math::{Pose, Vector};

/// nalgebra -> parry vector.
#[inline(always)]
pub fn to_parry(v: &Vector3<f32>) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

/// parry -> nalgebra vector.
#[inline(always)]
pub fn from_parry(v: Vector) -> Vector3<f32> {
    Vector3::new(v.x, v.y, v.z)
}

/// A parry pose from a translation (mm) and a unit quaternion.
#[inline]
pub fn pose(translation_mm: &Vector3<f32>, rotation: &UnitQuaternion<f32>) -> Pose {
    let q = rotation.quaternion();
    Pose::from_parts(
        to_parry(translation_mm),
        Quat::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

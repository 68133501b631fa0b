//! The suture tests' skin block: 40 x 30 x 10 mm, its top face on z = 0, centred on the z axis.

use nalgebra::Vector3;

/// How far inside the block at rest a point lies, mm (negative: outside).
pub fn depth_in_block_mm(p: &Vector3<f32>) -> f32 {
    (20.0 - p.x.abs())
        .min(15.0 - p.y.abs())
        .min(-p.z)
        .min(p.z + 10.0)
}

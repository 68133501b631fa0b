//! The suture tests' skin block: 40 x 30 x 10 mm, its top face on z = 0, centred on the z axis, and the world
//! around it (worlds/suture_block.toml).
#![allow(dead_code)] // each test binary uses its own subset

use nalgebra::Vector3;

/// How far inside the block at rest a point lies, mm (negative: outside).
pub fn depth_in_block_mm(p: &Vector3<f32>) -> f32 {
    (20.0 - p.x.abs())
        .min(15.0 - p.y.abs())
        .min(-p.z)
        .min(p.z + 10.0)
}

/// worlds/suture_block.toml (this block, a needle driver as tool 0 and a grasper as tool 1) and its driver's
/// spec.
pub fn suture_block() -> (
    sinew_server::scene::World,
    sinew_server::interaction::suture::NeedleDriverSpec,
) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture_block.toml");
    let world = sinew_server::world::load_world(&path).unwrap();
    let sinew_server::world::InstrumentSpec::NeedleDriver(spec) = world.tools[0].instrument else {
        panic!("tool 0 of the suture block is not a needle driver");
    };
    (world, spec)
}

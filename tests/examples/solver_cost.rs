//! Exploratory: contact-stiffness solve size and iterations under a press; time of Sim::step with it.
#![allow(clippy::unwrap_used, clippy::expect_used)]
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_testkit::harness::load_shipped_world;
fn main() {
    let world = load_shipped_world("pad.toml").unwrap();
    let mut sim = Sim::new(&world).unwrap();
    let mut out = vec![ToolOutput::default(); 2];
    let mut times = Vec::new();
    for tick in 0..3000 {
        let depth = (tick as f32 / 500.0).min(1.0) * 5.0;
        let cmd = ToolCommand {
            active: true,
            position_device_mm: [0.0, 0.0, 4.0 - depth],
            ..ToolCommand::default()
        };
        let t = std::time::Instant::now();
        sim.step(0.001, &[cmd], &mut out);
        times.push(t.elapsed().as_micros());
        if tick % 250 == 0 {
            let r = sim.tools[0].contact_response(0);
            println!(
                "tick {tick} F {:.3} held {} K {:?} iters {:?} nodes {:?}",
                out[0].force_world_n.z,
                out[0].held_nodes,
                out[0].stiffness_n_per_mm.diagonal().as_slice(),
                r.map(|r| r.iterations),
                r.map(|r| r.nodes)
            );
        }
    }
    times.sort();
    println!(
        "step p50 {} us p99 {} us",
        times[times.len() / 2],
        times[times.len() * 99 / 100]
    );
}

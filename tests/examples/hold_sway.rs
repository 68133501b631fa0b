//! Exploratory: moderated_over_zenoh.rs's scenario on virtual time (pad, two nominal hands pressing 10 mm deep
//! 14 mm either side of the centre) at zero delay, at 100 ms, and at 100 ms with +-20 ms jitter and 5% loss: the
//! hold's force peak-to-peak and stylus speed RMS over 2-4 s and 4-6 s (the sideways sway, BENCHMARKS.md).
//! `cargo run --release -p sinew-testkit --example hold_sway`
#![allow(clippy::unwrap_used)]
use hapticserver::{HandPreset, HandScript, ModePolicy};
use sinew_testkit::drill::{DrillDevice, Link, hold_metrics, run_drill};
use sinew_testkit::harness::load_shipped_world;
fn main() {
    let world = load_shipped_world("pad.toml").unwrap();
    for (rtt, jitter, loss) in [(0.0, 0.0, 0.0), (100.0, 0.0, 0.0), (100.0, 20.0, 0.05)] {
        let dev = |id: &str, x: f32, seed: u64| {
            let mut link = Link::rtt(rtt);
            link.jitter_ms = jitter;
            link.loss = loss;
            link.seed = seed;
            DrillDevice {
                id: id.into(),
                hand: HandPreset::Nominal,
                script: HandScript::Press {
                    at_mm: [x, 0.0, 0.0],
                    depth_mm: 10.0,
                    approach_mm: 10.0,
                    descend_s: 1.0,
                },
                link,
                mode: ModePolicy::Moderated,
            }
        };
        let r = run_drill(&world, &[dev("left", 14.0, 1), dev("right", -14.0, 2)], 6.0).unwrap();
        for d in 0..2 {
            for (a, b) in [(2.0, 4.0), (4.0, 6.0)] {
                let h = hold_metrics(&r.traces[d], a, b);
                println!("rtt {rtt} jitter {jitter} loss {loss} dev {d} {a}-{b} s: {h:?}");
            }
        }
    }
}

//! Exploratory: one drill, metrics printed. `cargo run --release -p sinew-testkit --example drill_explore -- <world> <hand> <mode> <rtt_ms>`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use hapticserver::{HandPreset, HandScript, ModePolicy};
use sinew_testkit::drill::*;
use sinew_testkit::harness::load_shipped_world;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let world = load_shipped_world(args.get(1).map_or("pad.toml", |s| s.as_str())).unwrap();
    let hand: HandPreset = args.get(2).map_or("light", |s| s.as_str()).parse().unwrap();
    let mode: ModePolicy = args
        .get(3)
        .map_or("moderated", |s| s.as_str())
        .parse()
        .unwrap();
    let rtt: f64 = args.get(4).map_or(100.0, |s| s.parse().unwrap());
    let depth: f32 = args.get(5).map_or(4.0, |s| s.parse().unwrap());
    let jitter: f64 = args.get(6).map_or(0.0, |s| s.parse().unwrap());
    let loss: f64 = args.get(7).map_or(0.0, |s| s.parse().unwrap());
    let device = DrillDevice {
        id: "left".into(),
        hand,
        script: HandScript::Press {
            at_mm: [0.0; 3],
            depth_mm: depth,
            approach_mm: 10.0,
            descend_s: 1.0,
        },
        link: Link {
            rtt_ms: rtt,
            jitter_ms: jitter,
            loss,
            seed: args.get(8).map_or(3, |s| s.parse().unwrap()),
        },
        mode,
    };
    let t0 = std::time::Instant::now();
    let r = run_drill(&world, &[device], 5.0).unwrap();
    let tr = &r.traces[0];
    let hold = hold_metrics(tr, 3.0, 5.0);
    println!(
        "wall {:.1} s; hold {:?}; energy out {:.3} mJ; sent {} ({:.0}/s); stale {}; withheld {:.3} mJ; max F {:.2}; max step {:.3}; drift {:?}",
        t0.elapsed().as_secs_f64(),
        hold,
        energy_output_mj(tr),
        r.commands_sent[0],
        r.commands_sent[0] as f64 / 5.0,
        r.stale_events[0],
        r.passivity_withheld_mj[0],
        r.max_force_n[0],
        max_force_step(tr, 0.0, 5.0),
        drift_mm(&r, 0, 3.0, 5.0)
    );
    for s in tr.iter().step_by(250) {
        println!(
            "t {:.2} z {:+.3} vz {:+.2} Fz {:+.3} w {:.1} stale {}",
            s.t_s, s.position_mm[2], s.velocity_mm_s[2], s.force_n[2], s.model_weight, s.stale
        );
    }
}

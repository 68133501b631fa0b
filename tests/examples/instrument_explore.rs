//! Exploratory: one instrument world against zero delay, the fidelity rows and (with `SINEW_TRACE=<device>`, `SINEW_TRACE_FROM/TO` s,
//! `SINEW_TRACE_STEP` ticks) the trace beside the zero-delay one. `cargo run --release -p sinew-testkit --example instrument_explore -- [world|all] [hand|all] [rtt...]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use hapticserver::HandPreset;
use sinew_testkit::drill::Link;
use sinew_testkit::fidelity::fidelity;
use sinew_testkit::harness::load_shipped_world;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let worlds: Vec<&str> = match args.get(1).map(String::as_str) {
        Some("all") | None => vec![
            "grasp_pull.toml",
            "cut.toml",
            "cut_under_tension.toml",
            "cautery.toml",
        ],
        Some(w) => vec![w],
    };
    let hands: Vec<HandPreset> = match args.get(2).map(String::as_str) {
        Some("all") | None => vec![HandPreset::Light, HandPreset::Nominal, HandPreset::Firm],
        Some(h) => vec![h.parse().unwrap()],
    };
    let rtts: Vec<f64> = if args.len() > 3 {
        args[3..].iter().map(|s| s.parse().unwrap()).collect()
    } else {
        vec![50.0, 100.0, 200.0]
    };
    println!(
        "| world | device | hand | round trip | peak (delayed / zero) | RMS (delayed / zero) | withheld | clamp | max step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for world_name in &worlds {
        // `pad_friction.toml`: the pad with Coulomb friction 0.5 (as the golden traces make it).
        let world = if *world_name == "pad_friction.toml" {
            let mut world = load_shipped_world("pad.toml").unwrap();
            world.objects[0].material.friction_coefficient = 0.5;
            world
        } else {
            load_shipped_world(world_name).unwrap()
        };
        for &hand in &hands {
            for &rtt in &rtts {
                let f = fidelity(&world, hand, Link::rtt(rtt), Link::rtt(rtt)).unwrap();
                if std::env::var("SINEW_TRACE").is_ok() {
                    dump(&f);
                }
                for row in f.rows(world_name.trim_end_matches(".toml"), hand, rtt) {
                    println!("{row}");
                }
            }
        }
    }
}

/// With `SINEW_TRACE=1`: the left device's trace every 100 ms, zero delay beside delayed.
#[allow(dead_code)]
fn dump(f: &sinew_testkit::fidelity::Fidelity) {
    let i: usize = std::env::var("SINEW_TRACE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let (d, r) = (&f.delayed.traces[i], &f.reference.traces[i]);
    let env = |k: &str, default: f64| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default)
    };
    let (from_s, to_s, step) = (
        env("SINEW_TRACE_FROM", 0.0),
        env("SINEW_TRACE_TO", 99.0),
        env("SINEW_TRACE_STEP", 100.0),
    );
    for (a, b) in d
        .iter()
        .zip(r)
        .step_by(step as usize)
        .filter(|(a, _)| a.t_s >= from_s && a.t_s <= to_s)
    {
        println!(
            "t {:.1} pos {:+6.2} {:+6.2} {:+6.2} | ref {:+6.2} {:+6.2} {:+6.2} | F {:+.3} {:+.3} {:+.3} target {:+.3} {:+.3} {:+.3} | ref F {:+.3} {:+.3} {:+.3} | w {:.1} E {:.1}",
            a.t_s,
            a.position_mm[0],
            a.position_mm[1],
            a.position_mm[2],
            b.position_mm[0],
            b.position_mm[1],
            b.position_mm[2],
            a.force_n[0],
            a.force_n[1],
            a.force_n[2],
            a.target_n[0],
            a.target_n[1],
            a.target_n[2],
            b.force_n[0],
            b.force_n[1],
            b.force_n[2],
            a.model_weight,
            a.passivity_energy_mj
        );
    }
}

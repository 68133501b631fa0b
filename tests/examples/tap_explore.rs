//! Exploratory: the tap transient drill, with the largest force steps and the energy account around them.
//! `cargo run --release -p sinew-testkit --example tap_explore -- <hand> <rtt_ms> <jitter_ms> <loss> <seed>`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use hapticserver::{HandPreset, ModePolicy};
use sinew_testkit::drill::*;
use sinew_testkit::harness::load_shipped_world;
use sinew_testkit::scenarios;

/// One trace sample's z components, the pre-passivity force, the blend offset and the energy account.
fn print_sample(s: &hapticserver::TraceSample) {
    println!(
        "t {:.3} z {:+.3} vz {:+7.2} Fz {:+.4} target {:+.4} blend {:+.4} E {:+.4} stale {}",
        s.t_s,
        s.position_mm[2],
        s.velocity_mm_s[2],
        s.force_n[2],
        s.target_n[2],
        s.blend_offset_n[2],
        s.passivity_energy_mj,
        s.stale
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let world = load_shipped_world(args.get(6).map_or("pad.toml", |s| s.as_str())).unwrap();
    let hand: HandPreset = args.get(1).map_or("light", |s| s.as_str()).parse().unwrap();
    let rtt: f64 = args.get(2).map_or(100.0, |s| s.parse().unwrap());
    let jitter: f64 = args.get(3).map_or(20.0, |s| s.parse().unwrap());
    let loss: f64 = args.get(4).map_or(0.05, |s| s.parse().unwrap());
    let seed: u64 = args.get(5).map_or(5, |s| s.parse().unwrap());
    let device = DrillDevice {
        id: "left".into(),
        hand,
        script: if let Some(period) = std::env::var("STROKE")
            .ok()
            .and_then(|v| v.parse::<f32>().ok())
        {
            scenarios::stroke(period)
        } else if let Some(depth) = std::env::var("PRESS")
            .ok()
            .and_then(|v| v.parse::<f32>().ok())
        {
            scenarios::press(depth, 1.0)
        } else {
            scenarios::taps()
        },
        link: Link {
            rtt_ms: rtt,
            jitter_ms: jitter,
            loss,
            seed,
        },
        mode: ModePolicy::Moderated,
    };
    let dur: f64 = std::env::var("DUR")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(6.0);
    let r = run_drill(&world, std::slice::from_ref(&device), dur).unwrap();
    if std::env::var_os("REF").is_some() {
        let reference = run_drill(
            &world,
            &[DrillDevice {
                link: Link::rtt(0.0),
                ..device
            }],
            dur,
        )
        .unwrap();
        let (a, b) = (&r.traces[0], &reference.traces[0]);
        println!(
            "rms error fraction {:.3}",
            rms_error_fraction(a, b, 2.0, dur)
        );
        let every: usize = std::env::var("EVERY")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(10);
        for (s, q) in a
            .iter()
            .zip(b)
            .filter(|(s, _)| s.t_s >= 3.0 && s.t_s < 3.6)
            .step_by(every)
        {
            println!(
                "t {:.3} x {:+6.2} ref {:+6.2} | F {:+.3} {:+.3} {:+.3} ref {:+.3} {:+.3} {:+.3} | tgt {:+.3} {:+.3}",
                s.t_s,
                s.position_mm[0],
                q.position_mm[0],
                s.force_n[0],
                s.force_n[1],
                s.force_n[2],
                q.force_n[0],
                q.force_n[1],
                q.force_n[2],
                s.target_n[0],
                s.target_n[2]
            );
        }
        return;
    }
    let tr = &r.traces[0];
    println!(
        "max step {:.4} N; withheld {:.3} mJ; energy out {:.3} mJ",
        max_force_step(tr, 0.0, dur),
        r.passivity_withheld_mj[0],
        energy_output_mj(tr)
    );
    if let (Some(from), Some(to)) = (
        std::env::var("FROM")
            .ok()
            .and_then(|v| v.parse::<f64>().ok()),
        std::env::var("TO").ok().and_then(|v| v.parse::<f64>().ok()),
    ) {
        let every: usize = std::env::var("EVERY")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(5);
        for s in tr
            .iter()
            .filter(|s| s.t_s >= from && s.t_s < to)
            .step_by(every)
        {
            print_sample(s);
        }
        return;
    }
    let mut steps: Vec<(f32, usize)> = tr
        .windows(2)
        .enumerate()
        .map(|(i, w)| ((w[1].force_n[2] - w[0].force_n[2]).abs(), i + 1))
        .collect();
    steps.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut shown = Vec::new();
    for &(step, i) in steps.iter().take(40) {
        if shown.iter().any(|&j: &usize| j.abs_diff(i) < 30) {
            continue;
        }
        shown.push(i);
        println!("--- step {step:.4} N at t {:.3}", tr[i].t_s);
        for s in &tr[i.saturating_sub(6)..(i + 4).min(tr.len())] {
            print_sample(s);
        }
        if shown.len() >= 6 {
            break;
        }
    }
}

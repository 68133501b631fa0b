//! Exploratory: the tug of war (`sinew_testkit::fidelity::tug_of_war`) on a sheet held to its bed by other anchors,
//! at 0/0, 10/200, 200/10 and 200/200 ms: what each feels against zero delay, the hold, the sheet, and where the
//! sheet differs most (how tug_of_war.toml's looseness was chosen, BENCHMARKS.md).
//! `cargo run --release -p sinew-testkit --example tug_explore -- [world] [anchor N/mm] [hand]`
#![allow(clippy::unwrap_used, clippy::expect_used)]
use hapticserver::HandPreset;
use sinew_testkit::drill::Link;
use sinew_testkit::fidelity::{sheet_difference_mm, tug_of_war};
use sinew_testkit::harness::load_shipped_world;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut world =
        load_shipped_world(args.get(1).map_or("tug_of_war.toml", String::as_str)).unwrap();
    if let Some(a) = args.get(2) {
        world.objects[0].material.anchor_stiffness_n_per_mm = a.parse().unwrap();
    }
    let hand: HandPreset = args
        .get(3)
        .map_or(HandPreset::Nominal, |h| h.parse().unwrap());
    let zero = tug_of_war(&world, hand, Link::rtt(0.0), Link::rtt(0.0)).unwrap();
    for (l, r) in [(0.0, 0.0), (10.0, 200.0), (200.0, 10.0), (200.0, 200.0)] {
        let t = tug_of_war(&world, hand, Link::rtt(l), Link::rtt(r)).unwrap();
        println!(
            "{l}/{r} ms: right feels {:.3} N ({:+.1}%), left {:.3} N ({:+.1}%), withheld {:.2}/{:.2} mJ, hold p2p {:.4}/{:.4} N, clamp {:?}, stale {:?}, sheet {:.3} mm",
            t.right_feels_n,
            100.0 * (t.right_feels_n / zero.right_feels_n - 1.0),
            t.left_feels_n,
            100.0 * (t.left_feels_n / zero.left_feels_n - 1.0),
            t.withheld_mj[0],
            t.withheld_mj[1],
            t.hold[0].force_p2p_n,
            t.hold[1].force_p2p_n,
            t.clamped,
            t.stale_events,
            sheet_difference_mm(&t.sheet_mm, &zero.sheet_mm)
        );
        let mean_pos = |tr: &[hapticserver::TraceSample]| {
            let w: Vec<_> = tr.iter().filter(|s| s.t_s >= 4.0 && s.t_s < 4.9).collect();
            let mut m = [0.0f32; 3];
            for s in &w {
                for (a, p) in m.iter_mut().zip(s.position_mm) {
                    *a += p / w.len() as f32;
                }
            }
            m
        };
        for d in 0..2 {
            let peak = |tr: &[hapticserver::TraceSample]| {
                tr.iter()
                    .map(|s| (s.force_n.iter().map(|f| f * f).sum::<f32>().sqrt(), s.t_s))
                    .fold((0.0f32, 0.0f64), |m, x| if x.0 > m.0 { x } else { m })
            };
            let (p, pt) = peak(&t.traces[d]);
            let (z, zt) = peak(&zero.traces[d]);
            println!(
                "  device {d}: peak {p:.3} N at {pt:.3} s, zero delay {z:.3} N at {zt:.3} s ({:+.1}%)",
                100.0 * (p / z - 1.0)
            );
            let (a, b) = (mean_pos(&t.traces[d]), mean_pos(&zero.traces[d]));
            println!(
                "  device {d}: hold at {:+.3} {:+.3} {:+.3}, zero delay {:+.3} {:+.3} {:+.3}",
                a[0], a[1], a[2], b[0], b[1], b[2]
            );
        }
        let (mut worst, mut at) = (0.0f32, 0usize);
        for (i, (p, q)) in t.sheet_mm.iter().zip(&zero.sheet_mm).enumerate() {
            let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            if d > worst {
                worst = d;
                at = i;
            }
        }
        println!(
            "  worst node {at} at {:?} vs {:?}",
            t.sheet_mm[at], zero.sheet_mm[at]
        );
    }
}

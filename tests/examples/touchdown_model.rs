//! Exploratory: what the server's local model for the tug of war's right grasper carries around its touch-down
//! (0.6-1.3 s): in contact?, `K` along z, the nearest plane's stiffness, `f0`, at zero delay and 200 ms.
//! `cargo run --release -p sinew-testkit --example touchdown_model -- [rtt_ms] [device print step, ticks]`
//!
//! It found the touch-down overshoot of BENCHMARKS.md (a first plane carried a fixed 0.2 N/mm prior while the
//! sheet answers 0.001-0.04 N/mm as the contact grows: up to 0.3 N at the device before the contact's models
//! arrived); now the plane carries the touch-down solve of the tool's footprint (about 0.02 N/mm here).
#![allow(clippy::unwrap_used, clippy::expect_used)]
use hapticserver::{HandPreset, ModePolicy};
use sinew_protocol::ForceMode;
use sinew_testkit::drill::{DrillDevice, Link, run_drill_observed};
use sinew_testkit::fidelity::tug_scripts;
use sinew_testkit::harness::load_shipped_world;

fn main() {
    let rtt: f64 = std::env::args()
        .nth(1)
        .map_or(200.0, |a| a.parse().unwrap());
    let world = load_shipped_world("tug_of_war.toml").unwrap();
    let (left, right) = tug_scripts(&world);
    let devices: Vec<DrillDevice> = [("left", left), ("right", right)]
        .into_iter()
        .map(|(id, script)| DrillDevice {
            id: id.into(),
            hand: HandPreset::Nominal,
            script,
            link: Link::rtt(rtt),
            mode: ModePolicy::default(),
        })
        .collect();
    let mut tick = 0;
    let result = run_drill_observed(&world, &devices, 1.4, |_, commands| {
        tick += 1;
        if !(600..1300).contains(&tick) || tick % 10 != 0 {
            return;
        }
        if let Some(Some(c)) = commands.get(1)
            && let ForceMode::LocalModel(m) = &c.mode
        {
            let plane_k = m
                .active_planes()
                .first()
                .map_or(0.0, |p| p.stiffness_n_per_mm);
            println!(
                "server t {:.3}: contact {} Kzz {:.3} plane k {:.3} f0z {:.3} x0z {:.2}",
                tick as f64 / 1000.0,
                m.in_contact,
                m.stiffness_n_per_mm[2],
                plane_k,
                m.f0_n[2],
                m.x0_mm[2]
            );
        }
    })
    .unwrap();
    let step: usize = std::env::args().nth(2).map_or(20, |a| a.parse().unwrap());
    for s in result.traces[1]
        .iter()
        .filter(|s| (0.6..1.3).contains(&s.t_s))
        .step_by(step)
    {
        println!(
            "device t {:.3}: z {:.2} fz {:.3} model weight {:.2} blend {:.3}",
            s.t_s, s.position_mm[2], s.force_n[2], s.model_weight, s.blend_offset_n[2]
        );
    }
}

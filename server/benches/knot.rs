//! What reading a thread's knot costs (`interaction/suture/knot.rs`), beside the server tick it runs in once
//! every `KNOT_PERIOD_TICKS`, on one core, no network. Baseline: the whole `Sim::step` of
//! worlds/suture_block.toml with the needle driver held 60 mm up and its thread hanging (the tick the reading
//! runs inside), timed in the same run. Readings timed:
//! - the hanging thread (65 nodes, no crossing left once simplified): a reading as most ticks' are;
//! - an overhand knot laid along 65 nodes, read by a fresh reader each time (the state sum run) and by one
//!   reader again and again (the diagram unchanged: the last judgement reused);
//! - a square knot of 180 points (two trefoils joined, 6 crossings kept), fresh reader each time.
//!
//! Run: `cargo bench -p sinew-server --bench knot` (add `-- --ticks N` to change the count).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Instant;

use nalgebra::{UnitQuaternion, Vector3};
use sinew_protocol::rt::LatencyHistogram;
use sinew_server::interaction::suture::{KnotKind, KnotReader};
use sinew_server::sim::{KNOT_PERIOD_TICKS, Sim, ToolOutput};
use sinew_server::world::load_world;

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "../tests/common/tool_pose.rs"]
mod tool_pose;

use tool_pose::pose_command;

/// The trefoil `(sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t)` scaled `scale_mm` about `centre`, `samples`
/// points; `mirror` flips z.
fn trefoil(centre: Vector3<f64>, scale_mm: f64, samples: usize, mirror: bool) -> Vec<Vector3<f64>> {
    (0..samples)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / samples as f64;
            let z = -(3.0 * t).sin();
            centre
                + scale_mm
                    * Vector3::new(
                        t.sin() + 2.0 * (2.0 * t).sin(),
                        t.cos() - 2.0 * (2.0 * t).cos(),
                        if mirror { -z } else { z },
                    )
        })
        .collect()
}

/// `curve` opened at its point of largest x and resampled at `n` points evenly along it.
fn open_and_resample(curve: &[Vector3<f64>], n: usize) -> Vec<Vector3<f32>> {
    let start = (0..curve.len())
        .max_by(|&i, &j| curve[i].x.total_cmp(&curve[j].x))
        .unwrap();
    let open: Vec<_> = (1..=curve.len())
        .map(|k| curve[(start + k) % curve.len()])
        .collect();
    let length: f64 = open.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    let mut out = Vec::with_capacity(n);
    let (mut leg, mut at) = (0usize, 0.0f64);
    for k in 0..n {
        let u = length * k as f64 / (n - 1) as f64;
        while leg + 2 < open.len() && at + (open[leg + 1] - open[leg]).norm() < u {
            at += (open[leg + 1] - open[leg]).norm();
            leg += 1;
        }
        let seg = open[leg + 1] - open[leg];
        let share = ((u - at) / seg.norm().max(1e-12)).clamp(0.0, 1.0);
        out.push((open[leg] + seg * share).cast::<f32>());
    }
    out
}

fn time(ticks: usize, mut f: impl FnMut()) -> LatencyHistogram {
    let mut h = LatencyHistogram::new();
    for _ in 0..ticks {
        let t0 = Instant::now();
        f();
        h.record(t0.elapsed());
    }
    h
}

fn main() {
    let ticks = bench_args::count_arg("ticks", 2_000).expect("--ticks takes a count");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture_block.toml");
    let world = load_world(&path).unwrap();
    let device_origin = Vector3::from(world.tools[0].device_origin_in_world_mm);
    let mut sim = Sim::new(&world).unwrap();
    let level = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2);
    let up_high = Vector3::new(-60.0, 0.0, 60.0);
    let command = [
        pose_command(&up_high, &device_origin, &level),
        Default::default(),
    ];
    let mut out = [ToolOutput::default(); 2];
    for _ in 0..2_000 {
        sim.step(0.001, &command, &mut out);
    }
    let tick = time(ticks, || {
        sim.step(0.001, &command, &mut out);
    });
    let hanging = sim.tools[0].thread().unwrap().nodes_mm().to_vec();
    let up = Vector3::z();
    let mut reader = KnotReader::new();
    let read_hanging = time(ticks, || {
        let mut r = KnotReader::new();
        std::hint::black_box(r.read_thread(&hanging, up).unwrap());
    });
    assert_eq!(reader.read_thread(&hanging, up).unwrap(), KnotKind::None);
    let knot = open_and_resample(&trefoil(Vector3::zeros(), 3.5, 200, false), 65);
    let fresh_knot = time(ticks, || {
        let mut r = KnotReader::new();
        std::hint::black_box(r.read_thread(&knot, up).unwrap());
    });
    assert!(matches!(
        reader.read_thread(&knot, up).unwrap(),
        KnotKind::Throws(_)
    ));
    let again_knot = time(ticks, || {
        std::hint::black_box(reader.read_thread(&knot, up).unwrap());
    });
    let mut square = trefoil(Vector3::zeros(), 5.0, 90, false);
    let other = trefoil(Vector3::new(60.0, 0.0, 0.0), 5.0, 90, true);
    let (ia, ib) = (
        (0..square.len())
            .max_by(|&i, &j| square[i].x.total_cmp(&square[j].x))
            .unwrap(),
        (0..other.len())
            .min_by(|&i, &j| other[i].x.total_cmp(&other[j].x))
            .unwrap(),
    );
    let n = square.len();
    square.rotate_left((ia + 1) % n);
    let mut tail: Vec<_> = other.clone();
    let n = tail.len();
    tail.rotate_left((ib + 1) % n);
    square.extend(tail);
    let fresh_square = time(ticks, || {
        let mut r = KnotReader::new();
        std::hint::black_box(r.read_closed(&square, Vector3::z()).unwrap());
    });
    let KnotKind::Throws(t) = reader.read_closed(&square, Vector3::z()).unwrap() else {
        panic!("the square knot was not read as throws");
    };
    assert_eq!(t.name(), "square knot");
    let base = tick.percentile_ns(50.0) as f64;
    let row = |what: &str, h: &LatencyHistogram| {
        let p50 = h.percentile_ns(50.0) as f64;
        println!(
            "{what}: p50 {:.1} us p99 {:.1} us  (x{:.3} of the tick's p50; x{:.4} spread over {KNOT_PERIOD_TICKS} ticks)",
            p50 / 1e3,
            h.percentile_ns(99.0) as f64 / 1e3,
            p50 / base,
            p50 / base / KNOT_PERIOD_TICKS as f64,
        );
    };
    println!(
        "suture_block tick, thread hanging (baseline): p50 {:.1} us p99 {:.1} us over {ticks} ticks",
        base / 1e3,
        tick.percentile_ns(99.0) as f64 / 1e3
    );
    row("read the hanging thread, fresh reader", &read_hanging);
    row("read a 65-node overhand knot, fresh reader", &fresh_knot);
    row(
        "read it again, same reader (diagram unchanged)",
        &again_knot,
    );
    row("read a 180-point square knot, fresh reader", &fresh_square);
}

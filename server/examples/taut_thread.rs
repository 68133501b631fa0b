//! A thread pulled taut past its length between two held nodes, on the thread's own chain (no tissue, no
//! tools): how long its segments get and what tension its length solve reads. The figures behind
//! docs/suturing.md, "A taut thread between two held points".
//!
//! Run: `cargo run --release -p sinew-server --example taut_thread` (add a Newton step count, default 2).
//!
//! A 150 mm thread of 64 segments (the suture world's) hangs from its first node under gravity; its node 10 is
//! then held, carried 10 mm up and aside (the 23.4 mm between go slack) over 1 s, and drawn back down at
//! 4 mm/s until the two held nodes are 3.7 mm further apart than the thread between them is long. A converged
//! solve would leave those ten segments straight, each stretched by the same 16%, carrying `EA` times that.

#![allow(clippy::expect_used)] // a probe run by hand: a bad argument should stop it loudly

use sinew_server::interaction::suture::ThreadChain;
use sinew_server::tissue::Vec3;

fn main() {
    let newton: usize = std::env::args()
        .nth(1)
        .map_or(2, |a| a.parse().expect("a Newton step count"));
    let segments = 64;
    let segment_mm = 150.0 / segments as f32;
    let nodes: Vec<Vec3> = (0..=segments)
        .map(|i| Vec3::new(0.0, 0.0, -segment_mm * i as f32))
        .collect();
    // The suture thread's constants (interaction/suture/thread.rs): 0.1 mg/mm, EA 1000 N, drag 5/s, EI 0.5.
    let axial_rigidity_n = 1000.0;
    let mut chain =
        ThreadChain::new(&nodes, 1e-7 * segment_mm, axial_rigidity_n, 5.0).expect("a valid chain");
    chain.set_held(0, true, 0.0);
    chain.set_bending(0.5);
    let gravity = Vec3::new(0.0, 0.0, -9810.0);
    let h_s = 0.00025;
    for _ in 0..2000 {
        chain.step(h_s, &gravity, newton);
    }
    chain.set_held(10, true, 0.0);
    let start = chain.positions_mm[10];
    let between_mm = 10.0 * segment_mm;
    println!(
        "{newton} Newton steps a substep; held nodes 0 and 10, {between_mm:.2} mm of thread between them"
    );
    println!(
        "  t (s)  apart (mm)  longest segment (mm)  tension read (N)  tension of a straight stretch (N)"
    );
    for k in 0..=16_000 {
        let t = k as f32 * h_s;
        let off = if t < 1.0 {
            Vec3::new(-6.0 * t, 0.0, 8.0 * t)
        } else {
            Vec3::new(-6.0, 0.0, 8.0 - 4.0 * (t - 1.0))
        };
        chain.positions_mm[10] = start + off;
        chain.step(h_s, &gravity, newton);
        if k % 2000 == 0 {
            let apart = (chain.positions_mm[10] - chain.positions_mm[0]).norm();
            let longest = chain.positions_mm[..11]
                .windows(2)
                .map(|w| (w[1] - w[0]).norm())
                .fold(0.0f32, f32::max);
            let read = chain.tension_n()[..10]
                .iter()
                .fold(0.0f32, |a, &b| a.max(b));
            let straight = axial_rigidity_n * ((apart - between_mm) / between_mm).max(0.0);
            println!("  {t:5.2}  {apart:10.2}  {longest:20.3}  {read:16.3}  {straight:33.1}");
        }
    }
}

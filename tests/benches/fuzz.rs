//! The generated-input fuzzer at scale: `cargo bench -p sinew-testkit --bench fuzz -- [--decoders N] [--worlds N]
//! [--recordings N] [--seed S]` (defaults: 10,000,000 decoder inputs, 100,000 worlds, 10,000 recordings).
//! Prints, per target, the inputs tried, accepted, refused and crashed, and the rate; exits 1 on any crash,
//! printing the inputs that made the first ones.

use std::time::Instant;

use sinew_testkit::fuzz::{TargetReport, fuzz_decoders, fuzz_recordings, fuzz_world_loader};

fn arg(name: &str, default: u64) -> u64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn print(report: &TargetReport, seconds: f64) {
    println!(
        "{:<28} {:>11} inputs {:>11} accepted {:>11} refused {:>4} crashes  {:>9.0} inputs/s",
        report.name,
        report.inputs,
        report.accepted,
        report.refused,
        report.crash_count,
        report.inputs as f64 / seconds.max(1e-9)
    );
    for crash in &report.crashes {
        println!("  crash: {crash}");
    }
}

fn main() -> anyhow::Result<()> {
    let seed = arg("--seed", 20261124);
    let dir = std::env::temp_dir().join(format!("sinew-fuzz-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut reports = Vec::new();
    let started = Instant::now();
    reports.push((
        fuzz_decoders(seed, arg("--decoders", 10_000_000)),
        started.elapsed(),
    ));
    let started = Instant::now();
    reports.push((
        fuzz_world_loader(seed + 1, arg("--worlds", 100_000), &dir)?,
        started.elapsed(),
    ));
    let started = Instant::now();
    reports.push((
        fuzz_recordings(seed + 2, arg("--recordings", 10_000), &dir)?,
        started.elapsed(),
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let mut total = 0;
    let mut crashes = 0;
    for (report, elapsed) in &reports {
        print(report, elapsed.as_secs_f64());
        total += report.inputs;
        crashes += report.crash_count;
    }
    println!("total: {total} generated inputs, {crashes} crashes (seed {seed})");
    anyhow::ensure!(crashes == 0, "the fuzzer found crashes");
    Ok(())
}

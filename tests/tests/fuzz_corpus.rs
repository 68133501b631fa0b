//! A short run of the generated-input fuzzer (issue "Labs and sites"; `cargo bench -p sinew-testkit --bench fuzz` runs
//! millions): every decoder, the world loader with the simulation it builds, and the recording reader with the
//! replay of what it reads, each fed mutated valid input. No panic anywhere, and each target both accepts and
//! refuses some inputs (so the mutations reach past the first check, and the run can fail).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use sinew_testkit::fuzz::{TargetReport, fuzz_decoders, fuzz_recordings, fuzz_world_loader};

fn check(report: &TargetReport) {
    println!(
        "{}: {} inputs, {} accepted, {} refused, {} crashes",
        report.name, report.inputs, report.accepted, report.refused, report.crash_count
    );
    assert_eq!(
        report.crash_count,
        0,
        "{} panicked on generated input:\n{}",
        report.name,
        report.crashes.join("\n---\n")
    );
    assert!(report.accepted > 0 && report.refused > 0, "{report:?}");
}

/// One test, the targets one after another: the fuzzer silences the process's panic hook while it runs.
#[test]
fn decoders_world_loader_and_recording_reader_never_panic_on_generated_input() {
    check(&fuzz_decoders(1, 200_000));
    let dir = std::env::temp_dir().join(format!("sinew-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let worlds = fuzz_world_loader(2, 1_500, &dir).unwrap();
    let recordings = fuzz_recordings(3, 400, &dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    check(&worlds);
    check(&recordings);
}

//! The `sinew` binary's command line, run as a user runs it: every subcommand is listed, and bad input gets a
//! clear error and a failing exit status. (Being an integration test of this package, it is also what makes
//! `cargo test --workspace` build the binary that the test kit's recording tests run.)
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::process::Command;

fn sinew(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sinew"))
        .args(args)
        .output()
        .expect("the sinew binary runs")
}

#[test]
fn help_lists_every_subcommand() {
    let out = sinew(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for subcommand in ["demo", "replay", "report", "certs", "play-device", "info"] {
        assert!(
            text.contains(subcommand),
            "`{subcommand}` missing from:\n{text}"
        );
    }
}

#[test]
fn bad_input_is_refused_clearly() {
    let unknown = sinew(&["operate"]);
    assert!(!unknown.status.success());
    let text = String::from_utf8_lossy(&unknown.stderr);
    assert!(text.contains("operate"), "{text}");

    let missing = sinew(&["report", "/nonexistent/session.mcap"]);
    assert!(!missing.status.success());
    let text = String::from_utf8_lossy(&missing.stderr);
    assert!(text.contains("/nonexistent/session.mcap"), "{text}");
}

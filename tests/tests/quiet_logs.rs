//! A normal run prints no WARN or ERROR the user cannot act on (issue "Safe under faults", item 10): the real
//! `sinew-server`, a `hapticserver` pressing the pad and a headless `sinew-viewer`, as processes on loopback,
//! each ended by SIGTERM or its duration, print neither; nor does a `sinew-viewer --png` without
//! `XDG_RUNTIME_DIR`. (Before: zenoh's `Scouting delay elapsed before start
//! conditions are met` on every client start, and `Received Data for unknown key_expr` errors at shutdown.)
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::process::Command;
use std::time::Duration;

use sinew_protocol::network::with_udp_twin;
use sinew_testkit::harness::{free_loopback_endpoint, spawn_pad_server_process};
use sinew_testkit::netns::{role_binary, wait_output};

fn noise(output: &std::process::Output) -> Vec<String> {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    text.lines()
        .filter(|line| {
            line.contains("WARN")
                || line.contains("ERROR")
                || line.trim_start().starts_with("error")
        })
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_normal_session_prints_no_warning_or_error() {
    let endpoint = free_loopback_endpoint().unwrap();
    // wait_output ends it (and every child below) if it outlives its timeout.
    let server = spawn_pad_server_process(&endpoint, &[], true).unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    let mut haptic = Command::new(role_binary("hapticserver").unwrap());
    haptic.args(["--id", "left", "--script", "press", "--duration-s", "4"]);
    for connect in with_udp_twin(&endpoint) {
        haptic.args(["--connect", &connect]);
    }
    let haptic = haptic
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let viewer = Command::new(role_binary("sinew-viewer").unwrap())
        .args(["--headless", "--duration-s", "3", "--connect", &endpoint])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // An offscreen PNG, as on a CI runner or over ssh: no XDG_RUNTIME_DIR (the graphics stack's Wayland probe
    // printed `error: XDG_RUNTIME_DIR is invalid or not set` twice).
    let png_path = std::env::temp_dir().join(format!("sinew-quiet-{}.png", std::process::id()));
    let png = Command::new(role_binary("sinew-viewer").unwrap())
        .args(["--png"])
        .arg(&png_path)
        .args(["--connect", &endpoint])
        .env_remove("XDG_RUNTIME_DIR")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let png = wait_output(png, Duration::from_secs(60)).unwrap();
    let _ = std::fs::remove_file(&png_path);
    let viewer = wait_output(viewer, Duration::from_secs(20)).unwrap();
    let haptic = wait_output(haptic, Duration::from_secs(20)).unwrap();
    Command::new("kill")
        .args(["-TERM", &server.id().to_string()])
        .status()
        .unwrap();
    let server = wait_output(server, Duration::from_secs(10)).unwrap();
    for (role, output) in [
        ("sinew-server", &server),
        ("hapticserver", &haptic),
        ("sinew-viewer", &viewer),
        ("sinew-viewer --png", &png),
    ] {
        assert!(output.status.success(), "{role}: {}", output.status);
        let noise = noise(output);
        assert!(noise.is_empty(), "{role} printed:\n{}", noise.join("\n"));
    }
    let haptic_out = String::from_utf8_lossy(&haptic.stdout);
    assert!(
        haptic_out.contains("drives tool `left-probe`"),
        "{haptic_out}"
    );
}

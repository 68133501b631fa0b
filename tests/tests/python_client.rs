//! The wire for any language (issue "Labs and sites"): the Python client in `protocol/python` (eclipse-zenoh,
//! a codec written from `protocol/WIRE.md`) decodes and re-encodes every golden vector, and presses the pad of
//! a real server over real zenoh: a force along +z that grows with depth, none out of contact.
//! Needs `python3` with `eclipse-zenoh==1.10.2` (`.ci/run` installs it).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::path::{Path, PathBuf};
use std::process::Command;

use sinew_testkit::harness::{Pacing, serial, start_pad_server};

fn python_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("protocol")
        .join("python")
}

fn python(args: &[&str]) -> std::process::Output {
    Command::new("python3")
        .args(args)
        .env("PYTHONPATH", python_dir())
        .output()
        .expect("running python3 (install it: .ci/run does)")
}

#[test]
fn the_python_codec_reads_and_writes_every_golden_vector() {
    let script = python_dir().join("tests").join("test_wire.py");
    let out = python(&[script.to_str().unwrap()]);
    println!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "test_wire.py failed");
}

#[test]
fn a_python_device_presses_the_pad_of_a_real_server() {
    let _serial = serial();
    let zenoh = python(&["-c", "import zenoh"]);
    assert!(
        zenoh.status.success(),
        "python3 cannot import zenoh: `python3 -m pip install eclipse-zenoh==1.10.2` (.ci/run does): {}",
        String::from_utf8_lossy(&zenoh.stderr)
    );
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    let script = python_dir().join("tests").join("test_press.py");
    let out = python(&[script.to_str().unwrap(), "--connect", &endpoint]);
    println!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let stats = server.stats();
    server.stop();
    assert!(out.status.success(), "test_press.py failed");
    let left = stats
        .devices
        .iter()
        .find(|d| d.device_id == "left")
        .unwrap();
    println!("server saw: {left:?}");
    assert!(left.poses_received > 1000, "{left:?}");
    assert!(left.max_force_n > 0.3, "{left:?}");
    assert_eq!(stats.rejected.total(), 0, "{:?}", stats.rejected);
}

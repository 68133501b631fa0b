//! The `hapticserver` binary refuses script flags it cannot use, naming the flag, before it opens a session.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::process::Command;

fn refused(args: &[&str]) -> String {
    let output = Command::new(env!("CARGO_BIN_EXE_hapticserver"))
        .args(args)
        .args(["--duration-s", "0"])
        .output()
        .unwrap();
    assert!(!output.status.success(), "{args:?} was accepted");
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn script_flags_that_do_not_apply_or_are_out_of_range_are_named() {
    let err = refused(&["--script", "press", "--pull-mm", "1,2,3"]);
    assert!(
        err.contains("--pull-mm is for --script grasp-pull"),
        "{err}"
    );
    let err = refused(&["--script", "hold", "--hold-s", "2"]);
    assert!(err.contains("--hold-s is for --script grasp-pull"), "{err}");
    let err = refused(&["--script", "grasp-pull", "--hold-s=-1"]);
    assert!(err.contains("hold_s"), "{err}");
    let err = refused(&["--script", "grasp-pull", "--pull-mm", "1,inf,0"]);
    assert!(err.contains("1,inf,0"), "{err}");
    let err = refused(&["--start-delay-s=-2"]);
    assert!(err.contains("--start-delay-s"), "{err}");
    let err = refused(&["--script", "cut-line", "--stroke-mm=-5"]);
    assert!(err.contains("stroke_mm"), "{err}");
}

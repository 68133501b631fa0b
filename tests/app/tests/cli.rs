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

/// `sinew certs` run once per scene: the lab's CA is made once and reused, each scene gets its folder, the
/// router's file is rewritten with every scene's rules; re-issuing a scene, a bad scene name, and a CA whose
/// key is gone are refused, naming what is wrong, and change nothing.
#[test]
fn certs_add_scenes_to_one_lab_and_refuse_to_reissue_or_orphan() {
    let dir = std::env::temp_dir().join(format!("sinew-cli-certs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.to_str().unwrap();
    let certs = |scene: &str| sinew(&["certs", "--out", out, "--scene", scene]);
    assert!(certs("pad").status.success());
    let ca = std::fs::read(dir.join("ca.pem")).unwrap();
    let pad_server = std::fs::read(dir.join("pad/server.pem")).unwrap();
    let second = certs("cautery");
    assert!(second.status.success(), "{second:?}");
    assert_eq!(
        std::fs::read(dir.join("ca.pem")).unwrap(),
        ca,
        "the CA was replaced"
    );
    assert!(dir.join("cautery/device-left.pem").is_file());
    let router = std::fs::read_to_string(dir.join("zenohd.json5")).unwrap();
    for key in [
        "sinew/pad/device/left/pose",
        "sinew/cautery/device/right/pose",
    ] {
        assert!(router.contains(key), "{key} not in the router's rules");
    }

    let again = certs("pad");
    assert!(!again.status.success());
    let text = String::from_utf8_lossy(&again.stderr);
    assert!(text.contains("pad") && text.contains("re-issue"), "{text}");
    assert_eq!(
        std::fs::read(dir.join("pad/server.pem")).unwrap(),
        pad_server
    );

    let bad = certs("a/b");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("scene"));
    assert!(!dir.join("a").exists());

    std::fs::remove_file(dir.join("ca-key.pem")).unwrap();
    let orphan = certs("suture");
    assert!(!orphan.status.success());
    let text = String::from_utf8_lossy(&orphan.stderr);
    assert!(text.contains("ca-key.pem"), "{text}");
    assert_eq!(std::fs::read(dir.join("ca.pem")).unwrap(), ca);
    assert!(!dir.join("suture").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

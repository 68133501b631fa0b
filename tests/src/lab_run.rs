//! Running the roles as processes in a [`NetnsLab`] and reading what they leave: a server on a shipped world,
//! numbers out of a role's status line, the relay's loss count, and a hapticserver's `--trace-csv`.
//!
//! Owns: [`require_lab`], [`assert_namespaces_gone`], [`start_lab_server`], [`status_number`],
//! [`relay_loss`], [`read_trace`], [`final_line`], [`shipped_world`], and a grasp-pull script as
//! `hapticserver` flags with its trace shifted to script time ([`grasp_pull_args`], [`to_script_time`]).
//! Must not: build or tear down the lab itself (that is [`crate::netns`]) or judge a run (the tests do).

use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::Duration;

use hapticserver::{HandScript, Trace, TraceSample};

use crate::netns::{NetnsLab, role_binary};

/// The zenoh port a lab server listens on, TCP and UDP.
pub const LAB_SERVER_PORT: u16 = 7447;

/// How long [`start_lab_server`] gives the server to load its world and open its session.
pub const LAB_SERVER_START: Duration = Duration::from_millis(1500);

/// Panic unless a lab can be built here (for tests compiled with `cfg(netns_lab)`: the build saw a usable
/// lab, so it must still be there).
pub fn require_lab() {
    if let Err(reason) = NetnsLab::available() {
        panic!("the network-namespace lab is not usable: {reason}");
    }
}

/// Panic if any of `namespaces` still exists (after the lab that made them was dropped).
pub fn assert_namespaces_gone(namespaces: &[String]) {
    let left = NetnsLab::existing_lab_namespaces();
    for ns in namespaces {
        assert!(
            !left.contains(ns),
            "namespace {ns} still exists after the lab was dropped"
        );
    }
}

/// A shipped world's file: `worlds/<name>.toml`.
pub fn shipped_world(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../worlds")
        .join(format!("{name}.toml"))
}

/// `sinew-server` on `world` in the lab's server namespace, listening on TCP and UDP at
/// [`LAB_SERVER_PORT`], given [`LAB_SERVER_START`] to come up; with the two endpoints a device connects to
/// (TCP, UDP). `extra` is appended to the server's arguments.
pub fn start_lab_server(
    lab: &mut NetnsLab,
    world: &Path,
    extra: &[&str],
) -> anyhow::Result<(Child, String, String)> {
    let ip = lab.server_ip().to_string();
    let tcp = format!("tcp/{ip}:{LAB_SERVER_PORT}");
    let udp = format!("udp/{ip}:{LAB_SERVER_PORT}");
    let mut server = Command::new(role_binary("sinew-server")?);
    server
        .arg("--world")
        .arg(world)
        .args(["--listen", &tcp, "--listen", &udp])
        .args(extra);
    let server = lab.spawn_in_server_ns(&server)?;
    std::thread::sleep(LAB_SERVER_START);
    Ok((server, tcp, udp))
}

/// `key N` in a status line, e.g. `forces_rx 5123` for key `"forces_rx "`.
pub fn status_number(line: &str, key: &str) -> Option<f64> {
    line.split(key)
        .nth(1)?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// (lost, forwarded) frames summed over both directions of the relay's report ([`NetnsLab::stop_relay`]).
pub fn relay_loss(report: &str) -> (u64, u64) {
    report
        .lines()
        .filter(|l| l.contains("forwarded"))
        .fold((0, 0), |(lost, forwarded), line| {
            let n = |key| status_number(line, key).unwrap_or(0.0) as u64;
            (lost + n(" lost "), forwarded + n(" forwarded "))
        })
}

/// Read a hapticserver's `--trace-csv` file; the error names the file and the line.
pub fn read_trace(path: &Path) -> anyhow::Result<Vec<TraceSample>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("reading the trace {}: {e}", path.display()))?;
    Trace::parse_csv(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// The last line of a role's output that starts with `final:` (a hapticserver's closing report).
pub fn final_line(stdout: &str) -> Option<&str> {
    stdout.lines().rev().find(|l| l.starts_with("final:"))
}

/// A finished hapticserver's `final:` line; panics with its output and status when there is none.
pub fn expect_final_line(output: &std::process::Output) -> String {
    let stdout = String::from_utf8_lossy(&output.stdout);
    final_line(&stdout).map(str::to_owned).unwrap_or_else(|| {
        panic!(
            "no `final:` line ({}):\n{stdout}\n{}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

/// The command-line form of a grasp-pull script (`hapticserver --script grasp-pull ...`, as the tug of war's
/// scripts are). Panics for another script, or one whose pull does not take 1 s (the command line's).
pub fn grasp_pull_args(script: &HandScript) -> Vec<String> {
    let HandScript::GraspPull {
        at_mm,
        depth_mm,
        approach_mm,
        descend_s,
        settle_s,
        pull_mm,
        pull_s,
        hold_s,
    } = script
    else {
        panic!("the tug of war's scripts are grasp-pulls: {script:?}");
    };
    assert_eq!(*pull_s, 1.0, "the command line's grasp-pull pulls over 1 s");
    let vec3 = |v: &[f32; 3]| format!("{},{},{}", v[0], v[1], v[2]);
    [
        ("--script", "grasp-pull".to_owned()),
        ("--at-mm", vec3(at_mm)),
        ("--depth-mm", depth_mm.to_string()),
        ("--approach-mm", approach_mm.to_string()),
        ("--descend-s", descend_s.to_string()),
        ("--settle-s", settle_s.to_string()),
        ("--pull-mm", vec3(pull_mm)),
        ("--hold-s", hold_s.to_string()),
    ]
    .into_iter()
    .flat_map(|(flag, value)| [flag.to_owned(), value])
    .collect()
}

/// Shift a trace's clock to script time: the hand holds exactly still at its start until the script begins,
/// and the script's first tick moves it.
pub fn to_script_time(trace: &mut [TraceSample]) -> anyhow::Result<()> {
    let start_mm = trace.first().map(|s| s.position_mm).unwrap_or_default();
    let moved = trace
        .iter()
        .position(|s| s.position_mm != start_mm)
        .ok_or_else(|| anyhow::anyhow!("the scripted hand never moved"))?;
    let t0_s = trace[moved].t_s - 0.001;
    for sample in trace.iter_mut() {
        sample.t_s -= t0_s;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_numbers_and_relay_loss_are_read_from_the_lines_roles_print() {
        let line = "final: left: moderated ticks 8000 rtt p50 201000 us p99 203000 us (n=7900) force 0.12 N \
                    forces_rx 7800 longest gap 12.0 ms overruns 0 stale 0 clamped 0 rejects 0";
        assert_eq!(status_number(line, "rtt p50 "), Some(201_000.0));
        assert_eq!(status_number(line, "stale "), Some(0.0));
        assert_eq!(status_number(line, "absent "), None);
        let report = "tosrv [delay=100]: received 920 forwarded 900 (tcp 9 udp 891) lost 20 oversize 0\n\
                      todev [delay=100]: received 1122 forwarded 1100 (tcp 9 udp 1091) lost 22 oversize 0\nbridging";
        assert_eq!(relay_loss(report), (42, 2000));
        assert_eq!(final_line("a\nfinal: x\nb"), Some("final: x"));
    }
}

//! The tug of war on real stacks: `sinew-server` on worlds/tug_of_war.toml in one network namespace, two
//! `hapticserver` processes (left and right surgeon, the nominal hand, `--mode auto`) in another, joined by
//! the project's relay. Run once with no delay and no loss (the reference) and once at 100 ms each way with
//! 2% loss: the devices pick direct and moderated rendering for themselves, no silence reaches the device's
//! 50 ms rule while the scripts run, nothing reaches the clamp, and each surgeon feels the other's pull, and
//! the force's peak over the run (touch-down included) and over the tug, within 15% of the reference (the
//! remote-surgeons issue's acceptance on real stacks).
//!
//! Ignored (with the reason) where the build could not see root and a working `ip netns`; see
//! `tests/netns_lab.rs`. Needs the workspace binaries (`cargo test --workspace --release` builds them).

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::process::Command;
use std::time::Duration;

use hapticserver::TraceSample;
use sinew_server::world::load_world;
use sinew_testkit::fidelity::{TUG_BEFORE_S, TUG_RUN_S, peak_and_rms, tug_felt_n, tug_scripts};
use sinew_testkit::harness::serial;
use sinew_testkit::lab_run::{
    assert_namespaces_gone, expect_final_line, grasp_pull_args, read_trace, relay_loss,
    require_lab, shipped_world, start_lab_server, status_number, to_script_time,
};
use sinew_testkit::netns::{LabConfig, NetnsLab, role_binary, wait_output};

/// How long after its process started each scripted hand begins its script, s: the sessions join over the
/// slow path meanwhile (a device loop starts once its UDP link is up, or after 3 s without one).
const START_DELAY_S: f64 = 3.5;

/// One tug of war in a lab: per device (left, right), its closing status line and its trace in script time.
struct LabTug {
    finals: Vec<String>,
    traces: Vec<Vec<TraceSample>>,
    relay_report: String,
}

fn run_lab_tug(config: LabConfig, tag: &str) -> LabTug {
    let world_path = shipped_world("tug_of_war");
    let world = load_world(&world_path).unwrap();
    let (left, right) = tug_scripts(&world);
    let haptic_bin = role_binary("hapticserver").unwrap();
    let mut lab = NetnsLab::new(config).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let (mut server, tcp, udp) = start_lab_server(&mut lab, &world_path, &[]).unwrap();
    let run_s = START_DELAY_S + TUG_RUN_S + 0.3;
    let csv = |id: &str| {
        std::env::temp_dir().join(format!(
            "sinew-netns-tug-{tag}-{id}-{}.csv",
            std::process::id()
        ))
    };
    let mut children = Vec::new();
    for (id, script) in [("left", &left), ("right", &right)] {
        let mut haptic = Command::new(&haptic_bin);
        haptic
            .args(["--id", id, "--scene", &world.scene])
            .args(grasp_pull_args(script))
            .args(["--hand", "nominal", "--mode", "auto"])
            .args(["--connect", &tcp, "--connect", &udp])
            .args(["--start-delay-s", &START_DELAY_S.to_string()])
            .args(["--duration-s", &run_s.to_string()])
            .arg("--trace-csv")
            .arg(csv(id));
        children.push(lab.spawn_in_device_ns(&haptic).unwrap());
    }
    let mut finals = Vec::new();
    for child in children {
        let output = wait_output(child, Duration::from_secs(60)).unwrap();
        let line = expect_final_line(&output);
        println!("{tag}: {line}");
        finals.push(line);
    }
    let _ = server.kill();
    let _ = server.wait();
    let relay_report = lab.stop_relay().unwrap();
    drop(lab);
    assert_namespaces_gone(&namespaces);
    let traces = ["left", "right"]
        .map(|id| {
            let path = csv(id);
            let mut trace = read_trace(&path).unwrap();
            let _ = std::fs::remove_file(&path);
            to_script_time(&mut trace).unwrap();
            trace
        })
        .to_vec();
    LabTug {
        finals,
        traces,
        relay_report,
    }
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn a_tug_of_war_across_a_lossy_100_ms_path_is_felt_as_at_zero_delay_with_the_mode_chosen_by_auto() {
    let _serial = serial();
    require_lab();
    let reference = run_lab_tug(LabConfig::symmetric(0.0, 0.0, 0.0, 11), "0ms");
    let distant = run_lab_tug(LabConfig::symmetric(100.0, 0.0, 0.02, 11), "100ms");
    let max_force_n = hapticserver::sim_device::sim_device_model().max_force_n;
    // A device auto keeps direct has a round trip under the policy's switch to the local model (it would have
    // switched): the bound is the policy's, not this machine's speed (p50 2.03-2.95 ms measured here at zero
    // delay, with the two 1 kHz loops' phase).
    let hapticserver::ModePolicy::Auto {
        moderate_above_ms, ..
    } = hapticserver::ModePolicy::default()
    else {
        panic!("the default policy is not auto");
    };
    for (run, mode, rtt_us) in [
        (
            &reference,
            "direct",
            0.0..f64::from(moderate_above_ms) * 1000.0,
        ),
        (&distant, "moderated", 200_000.0..260_000.0),
    ] {
        for line in &run.finals {
            assert!(line.contains(&format!(": {mode} ")), "not {mode}: {line}");
            let rtt = status_number(line, "rtt p50 ").unwrap();
            assert!(rtt_us.contains(&rtt), "round trip p50 {rtt} us: {line}");
            // Nothing at the clamp; every message decoded.
            for key in ["clamped ", "rejects "] {
                assert_eq!(status_number(line, key), Some(0.0), "{key}in {line}");
            }
        }
        for trace in &run.traces {
            let (peak, _) = peak_and_rms(trace);
            assert!(peak < max_force_n * 0.999, "{peak} N: at the clamp");
            // No silence reached the 50 ms rule while the scripts ran (the stop's ramp at the end is one).
            let silent = trace
                .iter()
                .find(|s| s.stale && (0.0..TUG_RUN_S).contains(&s.t_s));
            assert!(silent.is_none(), "silence during the run: {silent:?}");
            assert!(
                trace.last().is_some_and(|s| s.t_s > TUG_RUN_S),
                "the trace ends before the run's end"
            );
        }
    }
    let (lost, forwarded) = relay_loss(&distant.relay_report);
    let rate = lost as f64 / (lost + forwarded).max(1) as f64;
    println!("{}", distant.relay_report);
    assert!(
        forwarded > 5000 && (0.01..0.035).contains(&rate),
        "relay lost {lost} of {} frames ({rate:.4}), expected about 2%",
        lost + forwarded
    );
    let mut rows = Vec::new();
    let mut faithful = true;
    for (device, id) in ["left", "right"].iter().enumerate() {
        let felt = |run: &LabTug| tug_felt_n(&run.traces[device]);
        // The tug: from before left's pull reaches right to the end of the run.
        let tug_peak = |run: &LabTug| {
            let tug: Vec<TraceSample> = run.traces[device]
                .iter()
                .filter(|s| (TUG_BEFORE_S.0..TUG_RUN_S).contains(&s.t_s))
                .copied()
                .collect();
            peak_and_rms(&tug).0
        };
        let run_peak = |run: &LabTug| peak_and_rms(&run.traces[device]).0;
        // Silences after the first force and before the script (the hand in the air): reported, not judged.
        let early_silences = distant.traces[device]
            .windows(2)
            .filter(|w| !w[0].stale && w[1].stale && w[1].t_s < 0.0)
            .count();
        let felt_ratio = felt(&distant) / felt(&reference);
        let run_ratio = run_peak(&distant) / run_peak(&reference);
        let peak_ratio = tug_peak(&distant) / tug_peak(&reference);
        rows.push(format!(
            "{id}: feels the pull {:.4} N at 100+100 ms, {:.4} N at 0 ms ({felt_ratio:.3}); peak of the tug {:.3} N vs \
             {:.3} N ({peak_ratio:.3}); peak of the run, touch-down included, {:.3} N vs {:.3} N ({:.3}); withheld {} mJ; silences before the script {early_silences}",
            felt(&distant),
            felt(&reference),
            tug_peak(&distant),
            tug_peak(&reference),
            run_peak(&distant),
            run_peak(&reference),
            run_ratio,
            status_number(&distant.finals[device], "withheld ").unwrap_or(f64::NAN),
        ));
        faithful &= [felt_ratio, peak_ratio, run_ratio]
            .iter()
            .all(|r| (0.85..=1.15).contains(r));
    }
    println!("{}", rows.join("\n"));
    assert!(
        felt_reference_is_a_pull(&reference),
        "the reference run felt no pull: {rows:?}"
    );
    assert!(
        faithful,
        "not within 15% of zero delay:\n{}",
        rows.join("\n")
    );
}

/// The zero-delay run is a tug of war at all: left feels its pull, right feels left's (the virtual-time drill
/// measures about 0.06 N at right).
fn felt_reference_is_a_pull(reference: &LabTug) -> bool {
    tug_felt_n(&reference.traces[0]) > 0.5 && tug_felt_n(&reference.traces[1]) > 0.03
}

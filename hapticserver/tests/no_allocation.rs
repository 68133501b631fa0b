//! The real-time contract of the device loop: once warm, `HapticLoop::tick` (read the device, encode and hand
//! over the pose, take the newest command from the inbox, render directly or through the local model, passivity,
//! safety, write the device, trace) allocates nothing; nor does the inbox's `accept` (the zenoh callback's
//! decode into the latest-value mailbox). Counted on this thread with a counting global allocator (the
//! server's, shared by path).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

#[path = "../../server/tests/common/counting_allocator.rs"]
mod counting_allocator;

use std::sync::Arc;
use std::time::Duration;

use counting_allocator::{Counting, assert_counting_works, count_this_thread};
use hapticserver::force_inbox::ForceInbox;
use hapticserver::haptic_loop::HapticLoop;
use hapticserver::{ForceSafety, HandScript, ModePolicy, SafetyConfig, SimDevice};
use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::{ContactPlane, ForceCommand, ForceMode, InstanceId, LocalModel};

#[global_allocator]
static GLOBAL: Counting = Counting;

const ME: InstanceId = InstanceId(0x1e);
const SERVER: InstanceId = InstanceId(0x5e);
const PERIOD: Duration = Duration::from_millis(1);

/// The server's command for tick `k`: a force into the hand and, for a moderated device, the local model of a
/// surface 2 mm below the device origin with one nearby plane.
fn command(k: u64, moderated: bool) -> Vec<u8> {
    let mut planes = [ContactPlane::default(); sinew_protocol::MAX_CONTACT_PLANES];
    planes[0] = ContactPlane {
        normal: [0.0, 0.0, 1.0],
        offset_mm: -2.0,
        stiffness_n_per_mm: 0.2,
        damping_n_s_per_mm: 0.0,
    };
    let model = LocalModel {
        server_time_ns: k * 1_000_000,
        in_contact: true,
        x0_mm: [0.0, 0.0, -2.0],
        f0_n: [0.0, 0.0, 0.4],
        stiffness_n_per_mm: [0.2, 0.2, 0.2, 0.0, 0.0, 0.0],
        damping_n_s_per_mm: [0.0; 6],
        radius_mm: 10.0,
        fade_mm: 2.0,
        planes,
        plane_count: 1,
        energy_allowance_mj: 1.0,
        // Every term the renderer has: a grasp's bilateral part on odd ticks, the drag of cutting, and
        // friction about the stick point on even ticks.
        attached: k % 2 == 1,
        cut_drag_n: 0.15,
        friction_coefficient: 0.5,
        stick_stiffness_n_per_mm: 1.5,
        cut_facet_mm: 1.0,
        // A needle's tip pressing, popped at the device: a new press every 50 ticks.
        puncture: sinew_protocol::PunctureTerm {
            press: (k / 50 + 1) as u32,
            pop_at_n: 0.3,
            tip_axis: [0.0, 0.0, -1.0],
            f0_after_n: [0.0, 0.0, 0.1],
            stiffness_after_n_per_mm: [0.2, 0.2, 0.0, 0.0, 0.0, 0.0],
            drag_after_n: 0.1,
            tip_lever_mm: [0.0, 0.0, -10.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        },
    };
    let command = ForceCommand {
        seq: k + 1,
        echo_pose_seq: k,
        echo_device_time_ns: k * 1_000_000,
        force_n: [0.0, 0.0, 0.4 + 0.1 * ((k as f32) * 0.01).sin()],
        mode: if moderated {
            ForceMode::LocalModel(model)
        } else {
            ForceMode::Direct
        },
        in_contact: true,
        device_instance: ME.0,
        pose_wait_us: Some(150),
    };
    encode_to_vec(SERVER, &command)
}

/// A loop whose simulated hand presses 3 mm down and holds, run for `ticks` with commands every tick (direct)
/// or every 7th (moderated, as the heartbeat); returns the allocations in the last `counted` ticks.
fn allocations(policy: ModePolicy, ticks: u64, counted: u64) -> (u64, f32) {
    let moderated = policy == ModePolicy::Moderated;
    let inbox = Arc::new(ForceInbox::new(ME));
    let device = SimDevice::new(HandScript::Press {
        at_mm: [0.0; 3],
        depth_mm: 3.0,
        approach_mm: 5.0,
        descend_s: 0.5,
    });
    let safety = ForceSafety::new(SafetyConfig::new(3.3)).unwrap();
    let mut haptic = HapticLoop::new(Box::new(device), safety, inbox.clone(), PERIOD);
    haptic.set_mode_policy(policy);
    haptic.record_trace(ticks as usize + 1);
    // Encoded before counting: the server's encoding is not the device's work.
    let payloads: Vec<Vec<u8>> = (0..ticks).map(|k| command(k, moderated)).collect();
    let mut published = 0u64;
    let mut run = |range: std::ops::Range<u64>, published: &mut u64| {
        for k in range {
            let now_ns = (k + 1) * 1_000_000;
            if !moderated || k % 7 == 0 {
                inbox.accept(&payloads[k as usize], now_ns).unwrap();
            }
            haptic.tick(now_ns, Some(PERIOD), &mut |pose: &[u8]| {
                *published += u64::from(!pose.is_empty());
                true
            });
        }
    };
    run(0..ticks - counted, &mut published);
    let allocations = count_this_thread(|| run(ticks - counted..ticks, &mut published));
    assert_eq!(published, ticks, "a tick published no pose");
    (allocations, haptic.rendered_force_n()[2])
}

#[test]
fn a_warm_device_loop_allocates_nothing_directly_or_through_the_local_model() {
    assert_counting_works();
    for policy in [ModePolicy::Direct, ModePolicy::Moderated] {
        let (allocations, force_z_n) = allocations(policy, 3000, 2000);
        println!(
            "{}: {allocations} allocations in 2000 warm ticks, rendering {force_z_n:.3} N",
            policy.name()
        );
        assert!(force_z_n > 0.1, "{}: nothing rendered", policy.name());
        assert_eq!(allocations, 0, "{}: a warm tick allocated", policy.name());
    }
}

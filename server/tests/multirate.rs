//! Multi-rate objects (issue 13): an object that steps every `N` ticks on a thread of its own, felt at every
//! tick through the local model of its latest step. These tests press the shipped `fem_block` stepped at
//! 200 Hz (every 5 ticks) against the same block stepped every tick, and check the hand-off's contract: the
//! same bits on a thread as inline, a force with no step at the hand-offs, a contact felt one period late at
//! most, and an object frozen (not a kick) when its thread is lost.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use common::{fem_block_move as move_to, fem_block_press as press, worlds};
use sinew_server::multirate::{StepJob, StepRunner};
use sinew_server::node::step_threads::ThreadRunner;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::{World, load_world};

/// The shipped fem_block, stepped every tick.
fn every_tick() -> World {
    load_world(&worlds().join("fem_block.toml")).expect("fem_block world loads")
}

/// The same block stepped at `step_hz` with one implicit step a period.
fn multi_rate(step_hz: u32) -> World {
    common::scene_edits::with_step_hz(
        every_tick(),
        0,
        f64::from(step_hz),
        (1.0 / f64::from(step_hz)) as f32,
    )
}

#[test]
fn the_block_rests_at_the_same_force_whatever_its_step_rate_and_as_stepped_every_tick() {
    // Each step pushes the tissue out of the tool and solves with the held nodes pinned (Signorini's
    // conditions for who stays held): the rest state is the static contact, whatever the step, and the same
    // as the block stepped every tick (which pins its held nodes the same way).
    let mut every = Sim::new(&every_tick()).unwrap();
    let mut sims: Vec<(u32, Sim)> = [100, 200, 500]
        .into_iter()
        .map(|hz| {
            let world = multi_rate(hz);
            assert_eq!(world.objects[0].ticks_per_step, 1000 / hz);
            let sim = Sim::new(&world).unwrap();
            assert_eq!(
                sim.objects[0].step_lane().unwrap().ticks_per_step(),
                1000 / hz
            );
            (hz, sim)
        })
        .collect();
    let mut from = 0.0;
    for depth in [1.0f32, 2.0, 3.0] {
        let reference = move_to(&mut every, from, depth, 300, 300)
            .pop()
            .unwrap()
            .force_world_n;
        let mut rested = Vec::new();
        for (hz, sim) in &mut sims {
            let outputs = move_to(sim, from, depth, 300, 300);
            let out = outputs.last().unwrap();
            assert!(
                out.in_contact && out.force_world_n.z > 0.0,
                "{hz} Hz, {depth} mm"
            );
            // Held still, the force is steady across hand-offs.
            let held = &outputs[outputs.len() - 100..];
            let z = held.iter().map(|o| o.force_world_n.z);
            let spread = z.clone().fold(f32::MIN, f32::max) - z.fold(f32::MAX, f32::min);
            assert!(
                spread < 0.01 * out.force_world_n.norm() + 1e-5,
                "{hz} Hz, {depth} mm: ripple {spread} N"
            );
            rested.push(out.force_world_n);
        }
        println!(
            "{depth} mm: {:.4} / {:.4} / {:.4} N at 100 / 200 / 500 Hz; stepped every tick {:.4} N",
            rested[0].z, rested[1].z, rested[2].z, reference.z
        );
        for f in &rested[1..] {
            assert!(
                (f - rested[0]).norm() < 0.01 * rested[0].norm(),
                "{rested:?}"
            );
        }
        assert!(
            (reference - rested[0]).norm() < 0.01 * reference.norm(),
            "every tick {reference:?}, {rested:?}"
        );
        from = depth;
    }
    let (_, slow) = &mut sims[1];
    // The local model's stiffness comes from the contact solve run with each step.
    let out = move_to(slow, 3.0, 3.0, 1, 10).pop().unwrap();
    assert!(
        out.stiffness_n_per_mm[(2, 2)] > 0.0,
        "{:?}",
        out.stiffness_n_per_mm
    );
    // Lift off: the force goes, and the surface comes back to rest.
    let out = move_to(slow, 3.0, -5.0, 200, 800).pop().unwrap();
    assert!(!out.in_contact && out.force_world_n.norm() == 0.0);
    let object = &slow.objects[0];
    let furthest = common::furthest_from_rest_mm(object);
    assert!(furthest < 0.05, "{furthest} mm from rest after release");
}

#[test]
fn pressing_at_constant_speed_the_force_has_no_step_at_the_hand_offs() {
    // Between hand-offs the tool feels f0 - K (x - x0); at a hand-off f0 and x0 jump to the new step's. With
    // a good K the two agree: the force at a hand-off moves no more than between ticks inside a step.
    let mut slow = Sim::new(&multi_rate(200)).unwrap();
    let outputs = move_to(&mut slow, 0.0, 3.0, 600, 0); // 5 mm/s
    let z: Vec<f32> = outputs.iter().map(|o| o.force_world_n.z).collect();
    let onset = z.iter().position(|&f| f > 0.0).expect("contact");
    let (mut at_hand_off, mut inside) = (0.0f32, 0.0f32);
    for k in onset + 20..z.len() {
        let change = (z[k] - z[k - 1]).abs();
        if k % 5 == 0 {
            at_hand_off = at_hand_off.max(change);
        } else {
            inside = inside.max(change);
        }
    }
    println!(
        "largest tick-to-tick change: {at_hand_off:.5} N at hand-offs, {inside:.5} N between (force {:.3} N)",
        z[z.len() - 1]
    );
    assert!(inside > 0.0);
    assert!(
        at_hand_off < 3.0 * inside + 1e-4,
        "hand-off steps of {at_hand_off} N against {inside} N between"
    );
}

#[test]
fn contact_is_felt_at_most_two_step_periods_after_the_every_tick_block_feels_it() {
    let mut fast = Sim::new(&every_tick()).unwrap();
    let mut slow = Sim::new(&multi_rate(200)).unwrap();
    let onset =
        |outputs: Vec<ToolOutput>| outputs.iter().position(|o| o.in_contact).expect("contact");
    let (a, b) = (
        onset(move_to(&mut fast, -2.0, 2.0, 400, 0)),
        onset(move_to(&mut slow, -2.0, 2.0, 400, 0)),
    );
    println!("contact at tick {a} every tick, {b} at 200 Hz");
    assert!(b >= a && b <= a + 10, "{a} against {b}");
}

#[test]
fn a_step_on_its_own_thread_gives_the_same_bits_as_one_run_inline() {
    let world = multi_rate(200);
    let mut inline = Sim::new(&world).unwrap();
    let mut threaded = Sim::new(&world).unwrap();
    let late = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    threaded.set_step_runners(|object| {
        let runner = ThreadRunner::spawn(object).unwrap();
        late.lock().unwrap().push(runner.counters());
        Box::new(runner)
    });
    let path = |k: usize| {
        let t = k as f32 * 0.001;
        ToolCommand {
            position_device_mm: [
                3.0 * (7.0 * t).sin(),
                2.0 * (5.0 * t).cos(),
                2.0 - 2.5 * (3.0 * t).sin().abs(),
            ],
            ..press(0.0)
        }
    };
    let (mut a, mut b) = ([ToolOutput::default(); 2], [ToolOutput::default(); 2]);
    for k in 0..800 {
        let commands = [path(k), ToolCommand::default()];
        inline.step(0.001, &commands, &mut a);
        threaded.step(0.001, &commands, &mut b);
        for axis in 0..3 {
            assert_eq!(
                a[0].force_world_n[axis].to_bits(),
                b[0].force_world_n[axis].to_bits(),
                "tick {k}: inline {:?}, threaded {:?}",
                a[0].force_world_n,
                b[0].force_world_n
            );
        }
        assert_eq!(a[0].stiffness_n_per_mm, b[0].stiffness_n_per_mm, "tick {k}");
    }
    assert!(a[0].in_contact, "the path presses");
    assert_eq!(
        common::position_bits(&inline.objects[0]),
        common::position_bits(&threaded.objects[0])
    );
    let waited: u64 = late
        .lock()
        .unwrap()
        .iter()
        .map(|c| c.late.load(std::sync::atomic::Ordering::Relaxed))
        .sum();
    println!(
        "the tick waited for {waited} of 160 threaded steps (no pacing here: the tick runs flat out)"
    );
}

/// A runner whose thread died: every job it is given is lost.
#[derive(Debug)]
struct LosesJobs;

impl StepRunner for LosesJobs {
    fn launch(&mut self, job: Box<StepJob>) {
        drop(job);
    }
    fn collect(&mut self) -> Option<Box<StepJob>> {
        None
    }
}

#[test]
fn a_lost_step_freezes_the_object_and_lets_go_of_the_tool_without_a_fault_kick() {
    let mut slow = Sim::new(&multi_rate(200)).unwrap();
    let pressed = move_to(&mut slow, 0.0, 2.0, 200, 200).pop().unwrap();
    assert!(pressed.in_contact);
    let frozen = slow.objects[0].state.positions_mm.clone();
    slow.set_step_runners(|_| Box::new(LosesJobs));
    let mut out = [ToolOutput::default(); 2];
    let mut faults = 0;
    for k in 0..50 {
        let report = slow.step(0.001, &[press(2.0), ToolCommand::default()], &mut out);
        faults += report.faults;
        let f = out[0].force_world_n;
        assert!(
            f.iter().all(|c| c.is_finite()) && f.norm() <= pressed.force_world_n.norm() + 1e-6,
            "tick {k}: {f:?}"
        );
    }
    // The first hand-off after the loss finds nothing: one fault, then the object stays where it was and
    // pushes on nothing (the device's rate limit takes the force down; no reset to rest moves the tissue).
    assert_eq!(faults, 1);
    assert!(slow.objects[0].step_lane().unwrap().lost());
    assert_eq!(out[0].force_world_n.norm(), 0.0);
    assert_eq!(slow.objects[0].state.positions_mm, frozen);
}

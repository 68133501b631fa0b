//! The thread on the suture block's needle, on virtual time: it hangs from the needle's tail at its length and
//! carries its own weight; it follows the needle; it falls onto the skin, lies on it, and over 10,000 ticks of
//! a randomly driven needle and a grasper chasing the thread, on each of four seeds (`SINEW_SEED=<n>` runs one),
//! no node ever ends a tick inside the skin or a tool, no segment cuts into the skin across its edges, no two
//! segments pass through each other, and the ticks allocate nothing. Laid over its own needle, it rests on
//! the wire and does not pass through it; a laid knot reads as a half knot and springs open without passing
//! through itself; laid between the hands it keeps the jaws' hold (and, not yet, stays tied drawn tight).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
#[path = "common/skin_block.rs"]
mod skin_block;
#[path = "common/tool_pose.rs"]
mod tool_pose;

use skin_block::{depth_in_block_mm, suture_block};
use tool_pose::pose_command;

use counting_allocator::{Counting, assert_counting_works, count_this_thread};

#[global_allocator]
static GLOBAL: Counting = Counting;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sinew_server::interaction::JawInput;
use sinew_server::interaction::suture::thread_self_contact::closest_params;
use sinew_server::interaction::suture::{STANDARD_GRAVITY_MM_PER_S2, THREAD_DIAMETER_MM};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};

const DT_S: f32 = 0.001;

/// The suture block's needle driver (tool 0), its shaft level along world +y, the needle's curve down.
struct Driver {
    sim: Sim,
    device_origin_mm: Vector3<f32>,
    grasper_origin_mm: Vector3<f32>,
    /// The needle's tail in the tool frame.
    tail_tool_mm: Vector3<f32>,
    thread_length_mm: f32,
}

impl Driver {
    fn new() -> Self {
        let (world, spec) = suture_block();
        Self {
            device_origin_mm: Vector3::from(world.tools[0].device_origin_in_world_mm),
            grasper_origin_mm: Vector3::from(world.tools[1].device_origin_in_world_mm),
            tail_tool_mm: (spec.tool_from_needle() * Point3::from(spec.arc.tail().point_mm)).coords,
            thread_length_mm: spec.thread.length_mm,
            sim: Sim::new(&world).unwrap(),
        }
    }

    fn level() -> UnitQuaternion<f32> {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2)
    }

    /// One tick with the tool's origin commanded to `origin_mm` (world) at `rotation`, the grasper away.
    fn step(&mut self, origin_mm: &Vector3<f32>, rotation: &UnitQuaternion<f32>) -> ToolOutput {
        self.step_both(origin_mm, rotation, None)
    }

    /// One tick with the needle driver at `origin_mm`, `rotation` and the grasper (upright) at `grasper_mm`.
    fn step_both(
        &mut self,
        origin_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        grasper_mm: Option<&Vector3<f32>>,
    ) -> ToolOutput {
        self.step_grasping(origin_mm, rotation, grasper_mm, false)[0]
    }

    /// [`Self::step_both`] with the grasper's jaws `closed` (or open); both tools' outputs.
    fn step_grasping(
        &mut self,
        origin_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        grasper_mm: Option<&Vector3<f32>>,
        closed: bool,
    ) -> [ToolOutput; 2] {
        let grasper = grasper_mm.map_or(ToolCommand::default(), |at| {
            let mut command =
                pose_command(at, &self.grasper_origin_mm, &UnitQuaternion::identity());
            command.jaws = JawInput {
                buttons: u32::from(closed),
                jaw_angle_rad: 0.0,
            };
            command
        });
        let command = [
            pose_command(origin_mm, &self.device_origin_mm, rotation),
            grasper,
        ];
        let mut out = [ToolOutput::default(); 2];
        let report = self.sim.step(DT_S, &command, &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
        out
    }

    fn nodes(&self) -> &[Vector3<f32>] {
        self.sim.tools[0].thread().unwrap().nodes_mm()
    }

    /// The needle's tail where the tool is now (world).
    fn tail_now(&self) -> Vector3<f32> {
        let tool = &self.sim.tools[0];
        let pose = Isometry3::from_parts(Translation3::from(tool.position_mm), tool.rotation);
        (pose * Point3::from(self.tail_tool_mm)).coords
    }

    fn length_mm(&self) -> f32 {
        self.sim.tools[0].thread().unwrap().chain().length_mm()
    }
}

/// How far inside the suture block's tools a point lies, mm (negative: outside): the needle driver's 1 mm
/// sphere at its origin, the grasper's capsule (3 mm half length along its z, 1.5 mm radius), each where the
/// sim has it now.
fn depth_in_tools_mm(sim: &Sim, p: &Vector3<f32>) -> f32 {
    let driver = &sim.tools[0];
    let in_driver = 1.0 - (p - driver.position_mm).norm();
    let grasper = &sim.tools[1];
    if !grasper.active {
        return in_driver;
    }
    let axis = grasper.rotation * Vector3::z();
    let along = (p - grasper.position_mm).dot(&axis).clamp(-3.0, 3.0);
    let core = grasper.position_mm + axis * along;
    in_driver.max(1.5 - (p - core).norm())
}

/// Over the thread's pairs of segments that share no node: the least distance between them, and how many pairs
/// passed through each other since `gaps` (each pair's closest-approach vector at the last call, updated): a
/// pair near each other (within 1 mm) both times, their closest points inside both segments, whose
/// closest-approach vector turned round (a negative dot product).
fn self_contact(nodes: &[Vector3<f32>], gaps: &mut [Option<Vector3<f32>>]) -> (f32, u32) {
    let segments = nodes.len() - 1;
    let mut least = f32::INFINITY;
    let mut passed = 0;
    for i in 0..segments {
        for j in i + 2..segments {
            let slot = &mut gaps[i * segments + j];
            let Some((s, t)) = closest_params(&nodes[i], &nodes[i + 1], &nodes[j], &nodes[j + 1])
            else {
                *slot = None;
                continue;
            };
            let gap = (nodes[i] + (nodes[i + 1] - nodes[i]) * s)
                - (nodes[j] + (nodes[j + 1] - nodes[j]) * t);
            least = least.min(gap.norm());
            let inside = s > 0.01 && s < 0.99 && t > 0.01 && t < 0.99;
            let near = gap.norm() < 1.0 && inside;
            if let Some(was) = *slot
                && near
                && gap.dot(&was) < 0.0
            {
                passed += 1;
            }
            *slot = near.then_some(gap);
        }
    }
    (least, passed)
}

#[test]
fn a_thread_hangs_from_the_needles_tail_at_its_length_and_carries_its_weight() {
    let mut d = Driver::new();
    let level = Driver::level();
    // Well clear of the skin block (which spans x -20..20).
    let origin = Vector3::new(-80.0, 0.0, 100.0);
    // Laid out level, it swings down and settles; the tension is read over the last second (its mean
    // carries the weight whatever swing is left).
    let mut tension_sum = 0.0f64;
    for tick in 0..4000 {
        d.step(&origin, &level);
        if tick >= 3000 {
            tension_sum += f64::from(d.sim.tools[0].thread().unwrap().chain().tension_n()[0]);
        }
    }
    let nodes = d.nodes().to_vec();
    let tail = d.tail_now();
    assert!(
        (nodes[0] - tail).norm() < 1e-4,
        "the thread's first node {:?} is not on the needle's tail {tail:?}",
        nodes[0]
    );
    let end = nodes[nodes.len() - 1];
    let length = d.length_mm();
    println!(
        "hanging: length {length:.3} mm of {}, end {:.2} mm below the tail and {:.3} mm off its vertical",
        d.thread_length_mm,
        tail.z - end.z,
        (end - tail).xy().norm()
    );
    assert!((length - d.thread_length_mm).abs() <= 0.01 * d.thread_length_mm);
    assert!(
        tail.z - end.z > 0.98 * d.thread_length_mm,
        "it does not hang straight down"
    );
    assert!((end - tail).xy().norm() < 2.0);
    // The first segment carries the weight of every node below it.
    let thread = d.sim.tools[0].thread().unwrap();
    let free_nodes = (nodes.len() - 1) as f32;
    let node_kg = 1.0e-7 * d.thread_length_mm / free_nodes;
    let weight_n = free_nodes * node_kg * STANDARD_GRAVITY_MM_PER_S2 / 1000.0;
    let tension = (tension_sum / 1000.0) as f32;
    println!("mean tension at the tail {tension:.3e} N, weight {weight_n:.3e} N");
    assert!(
        (tension - weight_n).abs() < 0.1 * weight_n,
        "tension {tension} N against a weight of {weight_n} N"
    );
    // The needle driver feels it, straight down.
    let pull = thread.pull_on_tail_n();
    assert!(pull.z < 0.0 && pull.xy().norm() < 0.05 * pull.norm());
}

#[test]
fn a_thread_follows_its_needle_at_its_length() {
    let mut d = Driver::new();
    let level = Driver::level();
    let start = Vector3::new(-80.0, 0.0, 100.0);
    for _ in 0..500 {
        d.step(&start, &level);
    }
    // 100 mm across in a second, then a turn of the wrist, then back.
    let mut longest = 0.0f32;
    for k in 0..2000 {
        let s = (k as f32 / 1000.0).min(1.0);
        let origin = start + Vector3::new(0.0, 100.0 * s, 0.0);
        let turn = UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            (k as f32 / 1000.0 - 1.0).max(0.0) * 1.5,
        );
        d.step(&origin, &(turn * level));
        assert!((d.nodes()[0] - d.tail_now()).norm() < 1e-3);
        longest = longest.max(d.length_mm());
    }
    println!("longest while following: {longest:.3} mm");
    assert!(longest <= 1.01 * d.thread_length_mm);
    // It trails behind the needle: its end is no longer below the start.
    let end = d.nodes()[d.nodes().len() - 1];
    assert!(end.y > 20.0, "the thread's end stayed behind at {end:?}");
}

/// A small xorshift: the test's randomness, the same every run.
struct Random(u64);

impl Random {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn between(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// What one randomised run saw (`random_run`).
#[derive(Debug, Default)]
struct Walk {
    /// The deepest any node ended a tick inside the skin, mm (negative: outside), and at which tick.
    deepest_in_skin_mm: f32,
    deepest_tick: usize,
    /// The deepest any point along a segment ended a tick inside the skin, mm (a segment cutting an edge).
    deepest_segment_in_skin_mm: f32,
    /// The deepest any free node ended a tick inside a tool, mm, and the ticks a tool touched the thread.
    deepest_in_tools_mm: f32,
    ticks_touching_tools: u32,
    /// The deepest any point along a segment (but the first, swaged into the needle) ended a tick inside a
    /// tool, mm (a segment cutting a tool's rim with its nodes outside).
    deepest_segment_in_tools_mm: f32,
    /// The least distance between segments that share no node, mm; pairs that passed through each other; ticks
    /// the thread's own contact held pairs apart.
    least_apart_mm: f32,
    passed_through: u32,
    /// The tick a pair first passed through each other.
    first_pass_tick: Option<usize>,
    ticks_self_touching: u32,
    /// The thread's crossings over itself seen from above as the walk starts, and at the 1000th tick.
    crossings_at_start: usize,
    crossings_at_1000: usize,
    ticks_resting: u32,
    allocations: u64,
}

/// How the thread lies when the random walk starts.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Start {
    /// Laid out level from over the block's middle and let fall onto it.
    Fallen,
    /// Then laid in a pile on the skin ([`pile_path`]): coils crossing each other, let settle.
    Piled,
}

/// How many pairs of the thread's segments (sharing no node) cross each other seen from above (in the x-y
/// plane).
fn crossings_seen_from_above(nodes: &[Vector3<f32>]) -> usize {
    let cross = |o: &Vector3<f32>, a: &Vector3<f32>, b: &Vector3<f32>| {
        (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
    };
    let segments = nodes.len() - 1;
    (0..segments)
        .flat_map(|i| (i + 2..segments).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            let (a0, a1, b0, b1) = (&nodes[i], &nodes[i + 1], &nodes[j], &nodes[j + 1]);
            cross(a0, a1, b0) * cross(a0, a1, b1) < 0.0
                && cross(b0, b1, a0) * cross(b0, b1, a1) < 0.0
        })
        .count()
}

/// A pile of thread on the suture block's skin for a needle whose tail is at `tail`: down from the tail to the
/// block's middle, then five coils of 5 mm radius, each shifted 2.5 mm along x from the last and rising 0.5 mm
/// (two diameters: laid clear of each other), so each coil crosses the one below it twice; the rest of the
/// thread runs on from the last coil's end.
fn pile_path(tail: Vector3<f32>) -> Vec<Vector3<f32>> {
    let start = Vector3::new(-6.0, 0.0, 0.6);
    let mut path = vec![tail, Vector3::new(start.x, start.y, tail.z.min(6.0)), start];
    let (radius, shift, coils) = (5.0, 2.5, 5.0f32);
    for k in 1..=(coils * 24.0) as usize {
        let t = std::f32::consts::TAU * k as f32 / 24.0;
        let turns = k as f32 / 24.0;
        path.push(Vector3::new(
            start.x + radius - radius * t.cos() + shift * turns,
            start.y + radius * t.sin(),
            start.z + 0.5 * turns,
        ));
    }
    let end = *path.last().unwrap();
    path.push(end + Vector3::new(0.0, -10.0, 0.0));
    path
}

/// 10,000 ticks of the needle wandering over the block and the grasper chasing the thread, from the thread let
/// fall onto it (and piled, for [`Start::Piled`]); the randomness from `seed`.
fn random_run(seed: u64, start: Start) -> Walk {
    let mut d = Driver::new();
    let level = Driver::level();
    // Laid out level from over the block's middle and let fall onto it.
    let mut origin = Vector3::new(0.0, 0.0, 30.0);
    for _ in 0..1500 {
        d.step(&origin, &level);
    }
    let thread = d.sim.tools[0].thread().unwrap();
    let resting = thread.resting_nodes();
    // Laid out level toward -x, most of its 150 mm lies beyond the 40 mm block: it slides over the edge and
    // hangs down the side, still resting on the edge.
    assert!(resting >= 1, "the thread fell past the skin");
    let radius = 0.5 * THREAD_DIAMETER_MM;
    let deepest = |d: &Driver| {
        d.nodes()
            .iter()
            .map(depth_in_block_mm)
            .fold(f32::NEG_INFINITY, f32::max)
    };
    assert!(deepest(&d) <= -0.9 * radius);
    if start == Start::Piled {
        let path = pile_path(d.tail_now());
        assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&path));
        assert!(
            deepest(&d) <= -0.9 * radius,
            "the pile was laid in the skin"
        );
    }
    let crossings_at_start = crossings_seen_from_above(d.nodes());
    let mut random = Random(seed);
    let mut target = origin;
    let mut yaw = 0.0f32;
    let mut yaw_target = 0.0f32;
    // The grasper wanders too, from one of the thread's nodes to another, above the skin (its capsule's
    // bottom at least 0.5 mm over it).
    let mut grasper = Vector3::new(20.0, 20.0, 20.0);
    let mut grasper_target = grasper;
    let segments = d.nodes().len() - 1;
    let mut gaps = vec![None; segments * segments];
    let mut walk = Walk {
        crossings_at_start,
        deepest_in_skin_mm: f32::NEG_INFINITY,
        deepest_in_tools_mm: f32::NEG_INFINITY,
        deepest_segment_in_tools_mm: f32::NEG_INFINITY,
        deepest_segment_in_skin_mm: f32::NEG_INFINITY,
        least_apart_mm: f32::INFINITY,
        ..Walk::default()
    };
    for tick in 0..10_000 {
        // 100 mm/s in the first quarter, 400 mm/s in the last.
        let speed_mm_per_tick = 0.1 * (1 + tick / 2500) as f32;
        if (target - origin).norm() < 0.5 {
            target = Vector3::new(
                random.between(-35.0, 35.0),
                random.between(-30.0, 30.0),
                random.between(25.0, 45.0),
            );
            yaw_target = random.between(-2.0, 2.0);
        }
        let to = target - origin;
        origin += to * (speed_mm_per_tick / to.norm()).min(1.0);
        yaw += (yaw_target - yaw).clamp(-0.003, 0.003);
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * level;
        if (grasper_target - grasper).norm() < 0.5 {
            // Through where a random node of the thread is now, kept 5 mm over the skin's top.
            let node = d.nodes()[1 + (random.next() * 63.0) as usize];
            grasper_target = Vector3::new(
                node.x + random.between(-2.0, 2.0),
                node.y + random.between(-2.0, 2.0),
                node.z.max(5.0),
            );
        }
        let to = grasper_target - grasper;
        grasper += to * (speed_mm_per_tick / to.norm()).min(1.0);
        walk.allocations += count_this_thread(|| {
            d.step_both(&origin, &rotation, Some(&grasper));
        });
        // Not the first node: it is the needle's, held on its tail, and the grasper may pass through the
        // needle (the hands' tools do not meet each other).
        let in_tools = d.nodes()[1..]
            .iter()
            .map(|p| depth_in_tools_mm(&d.sim, p))
            .fold(f32::NEG_INFINITY, f32::max);
        walk.deepest_in_tools_mm = walk.deepest_in_tools_mm.max(in_tools);
        let segments_in_tools = d.nodes()[1..]
            .windows(2)
            .flat_map(|n| [0.25, 0.5, 0.75].map(|s| n[0] + (n[1] - n[0]) * s))
            .map(|p| depth_in_tools_mm(&d.sim, &p))
            .fold(f32::NEG_INFINITY, f32::max);
        walk.deepest_segment_in_tools_mm = walk.deepest_segment_in_tools_mm.max(segments_in_tools);
        // Touching: a node or a point along a segment (a segment put out of a tool whole rests on it between its
        // nodes).
        if in_tools.max(segments_in_tools) > -0.5 * THREAD_DIAMETER_MM - 0.01 {
            walk.ticks_touching_tools += 1;
        }
        if tick == 1000 {
            walk.crossings_at_1000 = crossings_seen_from_above(d.nodes());
        }
        let (least, passed) = self_contact(d.nodes(), &mut gaps);
        if passed > 0 && walk.passed_through == 0 {
            walk.first_pass_tick = Some(tick);
        }
        walk.least_apart_mm = walk.least_apart_mm.min(least);
        walk.passed_through += passed;
        let thread = d.sim.tools[0].thread().unwrap();
        if thread.pairs_held_apart() > 0 {
            walk.ticks_self_touching += 1;
        }
        if thread.resting_nodes() > 0 {
            walk.ticks_resting += 1;
        }
        let along_segments = d
            .nodes()
            .windows(2)
            .flat_map(|n| [0.25, 0.5, 0.75].map(|s| n[0] + (n[1] - n[0]) * s))
            .map(|p| depth_in_block_mm(&p))
            .fold(f32::NEG_INFINITY, f32::max);
        walk.deepest_segment_in_skin_mm = walk.deepest_segment_in_skin_mm.max(along_segments);
        let depth = deepest(&d);
        if depth > walk.deepest_in_skin_mm {
            walk.deepest_in_skin_mm = depth;
            walk.deepest_tick = tick;
        }
    }
    walk
}

/// Every seed's run keeps each node out of the skin, the tools and the thread itself, without allocating.
fn assert_kept_apart(seed: u64, walk: &Walk) {
    println!(
        "seed {seed}: deepest node {:.4} mm into the skin (tick {}; negative: outside), deepest point of a \
         segment {:.4} mm, {} ticks with the thread resting on it, {} allocations; deepest into a tool {:.4} mm \
         (a point along a segment {:.4} mm), {} ticks with a tool touching the thread; segments at least {:.4} mm apart, {} pairs passed through each other, {} ticks with the \
         thread touching itself",
        walk.deepest_in_skin_mm,
        walk.deepest_tick,
        walk.deepest_segment_in_skin_mm,
        walk.ticks_resting,
        walk.allocations,
        walk.deepest_in_tools_mm,
        walk.deepest_segment_in_tools_mm,
        walk.ticks_touching_tools,
        walk.least_apart_mm,
        walk.passed_through,
        walk.ticks_self_touching
    );
    assert_eq!(
        walk.passed_through, 0,
        "seed {seed}: the thread passed through itself (first at tick {:?})",
        walk.first_pass_tick
    );
    assert!(
        walk.least_apart_mm > 0.5 * THREAD_DIAMETER_MM,
        "seed {seed}: two segments came {} mm close",
        walk.least_apart_mm
    );
    assert!(
        walk.deepest_in_tools_mm <= 0.0,
        "seed {seed}: a node ended a tick {} mm inside a tool",
        walk.deepest_in_tools_mm
    );
    assert!(
        walk.deepest_segment_in_tools_mm <= 0.0,
        "seed {seed}: a segment ended a tick {} mm inside a tool",
        walk.deepest_segment_in_tools_mm
    );
    assert!(
        walk.deepest_segment_in_skin_mm <= 0.0,
        "seed {seed}: a segment cut {} mm into the skin",
        walk.deepest_segment_in_skin_mm
    );
    assert!(
        walk.deepest_in_skin_mm <= 0.0,
        "seed {seed}: a node ended a tick {} mm inside the skin at tick {}",
        walk.deepest_in_skin_mm,
        walk.deepest_tick
    );
    assert_eq!(walk.allocations, 0, "seed {seed}: the ticks allocated");
}

/// The thread piled on the skin in coils that cross one another ([`pile_path`]: 12 crossings seen from above),
/// then the random walk, 10,000 ticks on each of two seeds. The coils spring open within about ten ticks (the
/// thread's bending; none is left crossed by the 1000th tick), the thread touching itself as they do: no two
/// segments may pass through each other then, nor into the skin or a tool over the rest of the walk. Measured
/// (seeds 5-8): a pair passes through another on seeds 5, 6 and 8, at ticks 4-10, as the coils spring open.
#[test]
#[ignore = "known gap (issue 32): coils of 5 mm laid on the skin spring open within 10 ticks (the thread's bending, as a laid knot's), and on 3 of 4 seeds a pair passes through another as they do (docs/suturing.md, \"The thread on itself\")"]
fn a_thread_piled_on_itself_never_passes_through_itself_over_10000_random_ticks() {
    assert_counting_works();
    for seed in seeds(5..=6) {
        let walk = random_run(seed, Start::Piled);
        println!(
            "seed {seed}, piled: {} crossings seen from above as laid, {} at tick 1000",
            walk.crossings_at_start, walk.crossings_at_1000
        );
        assert_kept_apart(seed, &walk);
        assert!(
            walk.crossings_at_start >= 8,
            "the pile crosses itself {} times",
            walk.crossings_at_start
        );
        assert!(
            walk.ticks_self_touching >= 10,
            "seed {seed}: the thread touched itself only {} ticks",
            walk.ticks_self_touching
        );
    }
}

/// The seeds a test runs: `SINEW_SEED=<n>` runs that one alone.
fn seeds(shipped: std::ops::RangeInclusive<u64>) -> Vec<u64> {
    match std::env::var("SINEW_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        Some(seed) => vec![seed],
        None => shipped.collect(),
    }
}

#[test]
fn a_thread_lies_on_the_skin_and_never_passes_into_it_or_the_tools_over_10000_random_ticks() {
    assert_counting_works();
    // A random walk of the needle above the skin: targets anywhere over the block and beyond, reached at 100
    // to 400 mm/s, the wrist turned about the vertical; the needle (its lowest point 21 mm below the tool)
    // stays 4 mm above the skin, the thread drags over it, falls off its sides and is flung back on.
    let mut touching_tools = 0;
    let mut resting = 0;
    let chosen = seeds(1..=4);
    for &seed in &chosen {
        let walk = random_run(seed, Start::Fallen);
        assert_kept_apart(seed, &walk);
        touching_tools += walk.ticks_touching_tools;
        resting += walk.ticks_resting;
    }
    // What the shipped seeds exercise together (one seed may fling the thread off the block early: seed 0 leaves
    // it resting 44 ticks, so a seed run alone is not held to these).
    if chosen.len() > 1 {
        println!(
            "over the seeds: {touching_tools} ticks with a tool touching the thread, {resting} resting"
        );
        assert!(touching_tools > 100, "the tools seldom met the thread");
        assert!(resting > 3000, "the thread seldom touched the skin");
    }
}

/// The driver of a thread tool: warmed up (the tool come up to `origin`, the thread hanging from it), then
/// stepped until the next tick is one the knot watch reads on.
fn hanging_driver() -> (Driver, Vector3<f32>, UnitQuaternion<f32>) {
    let mut d = Driver::new();
    let level = Driver::level();
    let origin = Vector3::new(-80.0, 0.0, 100.0);
    for _ in 0..1500 {
        d.step(&origin, &level);
    }
    while !d
        .sim
        .steps()
        .is_multiple_of(sinew_server::sim::KNOT_PERIOD_TICKS)
    {
        d.step(&origin, &level);
    }
    (d, origin, level)
}

/// [`hanging_driver`] with an overhand knot laid in its thread ([`overhand_knot_path`] from the needle's
/// tail, returned last).
fn driver_with_a_laid_knot() -> (Driver, Vector3<f32>, UnitQuaternion<f32>, Vector3<f32>) {
    let (mut d, origin, level) = hanging_driver();
    let tail = d.tail_now();
    let path = overhand_knot_path(tail);
    assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&path));
    (d, origin, level, tail)
}

/// An overhand knot (the trefoil `(sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t)` scaled 3 mm: 86 mm of
/// thread bent no tighter than a 3.9 mm radius), 40 mm to -x of `tail`, opened at its point nearest the tail:
/// the path runs from the tail in there (30 mm), round the knot, out beside where it came in, and off to +x
/// and -y, below the tail.
fn overhand_knot_path(tail: Vector3<f32>) -> Vec<Vector3<f32>> {
    overhand_knot_path_at(tail, 40.0, 3.0)
}

/// [`overhand_knot_path`] with the knot `away_mm` to -x of the tail, scaled `scale_mm`.
fn overhand_knot_path_at(tail: Vector3<f32>, away_mm: f32, scale_mm: f32) -> Vec<Vector3<f32>> {
    let centre = tail + Vector3::new(-away_mm, 0.0, -5.0);
    let knot: Vec<Vector3<f32>> = (0..80)
        .map(|k| {
            let t = std::f32::consts::TAU * k as f32 / 80.0;
            centre
                + scale_mm
                    * Vector3::new(
                        t.sin() + 2.0 * (2.0 * t).sin(),
                        t.cos() - 2.0 * (2.0 * t).cos(),
                        -(3.0 * t).sin(),
                    )
        })
        .collect();
    let nearest = (0..knot.len())
        .max_by(|&i, &j| knot[i].x.total_cmp(&knot[j].x))
        .unwrap();
    let mut path = vec![tail];
    path.extend((1..=knot.len()).map(|k| knot[(nearest + k) % knot.len()]));
    path.push(tail + Vector3::new(10.0, -15.0, -10.0));
    path.push(tail + Vector3::new(60.0, -40.0, -10.0));
    path
}

/// A knot laid in the thread (`SutureThread::lay_along`) reaches the driver's output as a half knot at the
/// watch's next reading, with its hand; a thread laid in a loop that crosses itself reads as no knot; a path
/// that is no path is refused and changes nothing.
#[test]
fn a_knot_laid_in_the_thread_reaches_the_drivers_output() {
    use sinew_server::interaction::suture::KnotKind;
    let (mut d, origin, level, tail) = driver_with_a_laid_knot();
    let out = d.step(&origin, &level);
    let KnotKind::Throws(throws) = out.suture.knot else {
        panic!("the laid knot was not read: {:?}", out.suture.knot);
    };
    assert_eq!(throws.name(), "half knot");
    assert_eq!(
        (throws.single_right, throws.single_left),
        (0, 1),
        "{throws:?}"
    );
    // The reading holds between readings.
    let out = d.step(&origin, &level);
    assert_eq!(out.suture.knot, KnotKind::Throws(throws));
    // A loop that crosses itself ties nothing.
    let mut looped = vec![tail];
    for k in 0..=40 {
        let a = std::f32::consts::TAU * k as f32 / 40.0;
        looped.push(
            tail + Vector3::new(
                -20.0 + 12.0 * a.cos(),
                12.0 * a.sin(),
                -5.0 - 0.1 * k as f32,
            ),
        );
    }
    looped.push(tail + Vector3::new(-40.0, 0.0, -8.0));
    assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&looped));
    let mut out = ToolOutput::default();
    for _ in 0..sinew_server::sim::KNOT_PERIOD_TICKS {
        out = d.step(&origin, &level);
    }
    assert_eq!(out.suture.knot, KnotKind::None);
    // A path that is no path changes nothing.
    let before = d.nodes().to_vec();
    let thread = d.sim.tools[0].thread_mut().unwrap();
    assert!(!thread.lay_along(&[tail]));
    assert!(!thread.lay_along(&[tail, Vector3::new(f32::NAN, 0.0, 0.0)]));
    assert_eq!(d.nodes(), before.as_slice());
}

/// The same knot, springing open as it hangs (nodes 4-12 mm a tick): no two segments that do not share a node
/// ever end a tick closer than 90% of the thread's diameter, and none passes through another (measured 0.247
/// mm at closest; 0.113 mm before strands crossing took their side across both and the last self pass ran
/// until none was pushed, up to three times).
#[test]
fn a_laid_knot_springing_open_never_passes_through_itself() {
    let (mut d, origin, level, _) = driver_with_a_laid_knot();
    let (mut closest_mm, mut fastest_mm) = (f32::INFINITY, 0.0f32);
    let segments = d.nodes().len() - 1;
    let mut gaps = vec![None; segments * segments];
    let mut passed_through = 0;
    for _ in 0..300 {
        let before = d.nodes().to_vec();
        d.step(&origin, &level);
        passed_through += self_contact(d.nodes(), &mut gaps).1;
        let n = d.nodes();
        fastest_mm = n
            .iter()
            .zip(&before)
            .map(|(a, b)| (a - b).norm())
            .fold(fastest_mm, f32::max);
        for i in 0..n.len() - 1 {
            for j in i + 2..n.len() - 1 {
                if let Some((s, t)) = closest_params(&n[i], &n[i + 1], &n[j], &n[j + 1]) {
                    let gap =
                        ((n[i] + (n[i + 1] - n[i]) * s) - (n[j] + (n[j + 1] - n[j]) * t)).norm();
                    closest_mm = closest_mm.min(gap);
                }
            }
        }
    }
    println!(
        "a laid knot springing open: fastest node {fastest_mm:.2} mm a tick, closest segments {closest_mm:.3} mm, \
         {passed_through} pairs passed through each other"
    );
    assert_eq!(passed_through, 0, "the thread passed through itself");
    assert!(
        fastest_mm > 3.0,
        "the knot did not spring open fast: {fastest_mm} mm a tick"
    );
    assert!(
        closest_mm >= 0.9 * THREAD_DIAMETER_MM,
        "two segments came {closest_mm} mm apart"
    );
}

/// The knot laid between the hands: the grasper takes the hanging thread 136 mm along (node 58) and carries
/// it up beside where the knot will lie, then an overhand knot (55 mm from the tail, scaled 2.4 mm) is laid
/// from the needle's tail through the jaws, which keep their hold (`SutureThread::lay_along`), on a tick the
/// knot watch reads. Returns the driver, the needle driver's pose, the grasper's aim, its grip, and the way the
/// strand leaves the knot toward the jaws.
fn knot_between_the_hands() -> (
    Driver,
    Vector3<f32>,
    UnitQuaternion<f32>,
    Vector3<f32>,
    sinew_server::interaction::suture::ThreadGrip,
    Vector3<f32>,
) {
    const TAKEN_NODE: usize = 58;
    let (mut d, origin, level) = hanging_driver();
    let tail = d.tail_now();
    // The open grasper (its capsule upright, 1.5 mm radius) to 0.3 mm beside the hanging node, from 20 mm out.
    // (Following the node as it swings a little.)
    let mut grasper = d.sim.tools[1].position_mm;
    for beside_mm in [20.0, 1.5 + 0.3] {
        for _ in 0..20_000 {
            let waypoint = d.nodes()[TAKEN_NODE] + Vector3::new(beside_mm, 0.0, 0.0);
            let to = waypoint - grasper;
            grasper += to * (0.1 / to.norm().max(0.1));
            d.step_grasping(&origin, &level, Some(&grasper), false);
            if (d.sim.tools[1].position_mm - waypoint).norm() < 0.02 {
                break;
            }
        }
    }
    for _ in 0..50 {
        d.step_grasping(&origin, &level, Some(&grasper), true);
    }
    let grip = *d.sim.tools[0]
        .thread()
        .unwrap()
        .grip_of(1)
        .expect("the jaws did not take the thread");
    assert!(
        usize::abs_diff(grip.node as usize, TAKEN_NODE) <= 1,
        "took node {}",
        grip.node
    );
    // The knot's path up to where it leaves the knot, and the jaws' place on the way on from there: the thread
    // must reach them at the taken node's length (a bend in between takes up what the straight line lacks).
    let mut path = overhand_knot_path_at(tail, 55.0, 2.4);
    path.truncate(path.len() - 2);
    let laid_mm: f32 = path.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    let taken_at_mm = grip.node as f32 * d.length_mm() / (d.nodes().len() - 1) as f32;
    let left_mm = taken_at_mm - laid_mm;
    let exit = *path.last().unwrap();
    let out_of_knot = (tail + Vector3::new(10.0, -15.0, -10.0) - exit).normalize();
    let jaws_mm = exit + out_of_knot * (0.8 * left_mm);
    let held_at = |d: &Driver| {
        d.sim.tools[0]
            .thread()
            .unwrap()
            .grip_of(1)
            .unwrap()
            .place_mm()
    };
    for _ in 0..20_000 {
        let at = held_at(&d);
        if (at - jaws_mm).norm() < 0.01 {
            break;
        }
        let to = jaws_mm - at;
        grasper += to * (0.1 / to.norm().max(0.1));
        d.step_grasping(&origin, &level, Some(&grasper), true);
    }
    let at = held_at(&d);
    assert!(
        (at - jaws_mm).norm() < 0.01,
        "the jaws never reached {jaws_mm:?}"
    );
    let chord = at - exit;
    let rise = (0.25 * left_mm * left_mm - 0.25 * chord.norm_squared()).sqrt();
    let aside = chord.cross(&Vector3::z()).normalize();
    path.push(exit + 0.5 * chord + aside * rise);
    path.push(at);
    path.push(at + out_of_knot * 30.0);
    while !d
        .sim
        .steps()
        .is_multiple_of(sinew_server::sim::KNOT_PERIOD_TICKS)
    {
        d.step_grasping(&origin, &level, Some(&grasper), true);
    }
    assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&path));
    assert!(
        d.sim.tools[0].thread().unwrap().grip_of(1).is_some(),
        "laying the knot let go of the jaws"
    );
    (d, origin, level, grasper, grip, out_of_knot)
}

/// [`knot_between_the_hands`]: laying the knot keeps the jaws' hold, on the same node, where they hold it, and
/// the thread between the hands reads as a half knot; a path that does not run through the jaws lets go of
/// them.
#[test]
fn a_knot_laid_between_the_hands_keeps_the_jaws_hold() {
    use sinew_server::interaction::suture::{KnotKind, KnotReader};
    let (mut d, origin, level, grasper, grip, _) = knot_between_the_hands();
    let between = &d.nodes()[..=grip.node as usize];
    let reading = KnotReader::new()
        .read_thread(between, Vector3::z())
        .unwrap();
    assert!(
        matches!(reading, KnotKind::Throws(t) if t.name() == "half knot"),
        "{reading:?}"
    );
    let held = *d.sim.tools[0].thread().unwrap().grip_of(1).unwrap();
    assert_eq!(held.node, grip.node);
    assert!((d.nodes()[held.node as usize] - held.place_mm()).norm() < 1e-3);
    assert!(
        held.node as usize + 1 < d.nodes().len(),
        "nothing hangs past the jaws"
    );
    // Laid straight down from the tail instead: the path passes nowhere near the jaws, which let go.
    let tail = d.tail_now();
    let down = [tail, tail - Vector3::new(0.0, 0.0, 200.0)];
    assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&down));
    assert!(d.sim.tools[0].thread().unwrap().grip_of(1).is_none());
    d.step_grasping(&origin, &level, Some(&grasper), true);
}

/// The knot laid between the hands ([`knot_between_the_hands`]), drawn tight: the grasper draws its strand
/// away from the knot, the needle's tail held still, at 20 mm/s. The knot should tighten and stay a half knot
/// at every reading, no two strands passing through each other, the jaws feeling the pull rise, and the thread
/// between the hands ending far less slack than it was laid.
#[test]
#[ignore = "known gap (issue 32): the knot, laid partly inside the grasper's jaws, reads as none after the first tick's segment push, and drawn, the length solve drives strands through each other (docs/suturing.md, \"A knot drawn tight\", \"Segments out of the tools\")"]
fn a_laid_knot_drawn_tight_by_its_ends_stays_a_half_knot() {
    use sinew_server::interaction::suture::KnotKind;
    let (mut d, origin, level, mut grasper, grip, away) = knot_between_the_hands();
    let out = d.step_grasping(&origin, &level, Some(&grasper), true);
    let KnotKind::Throws(laid_knot) = out[0].suture.knot else {
        panic!("the laid knot was not read: {:?}", out[0].suture.knot);
    };
    let segments = d.nodes().len() - 1;
    let mut gaps = vec![None; segments * segments];
    let (mut passed_through, mut most_pull_n, mut readings) = (0, 0.0f32, Vec::new());
    let slack = |n: &[Vector3<f32>], to: usize| -> f32 {
        n[..=to]
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum::<f32>()
            - (n[to] - n[0]).norm()
    };
    let slack_laid_mm = slack(d.nodes(), grip.node as usize);
    let mut slipped = None;
    for tick in 1..=4000 {
        grasper += away * 0.02;
        let out = d.step_grasping(&origin, &level, Some(&grasper), true);
        passed_through += self_contact(d.nodes(), &mut gaps).1;
        let Some(held) = d.sim.tools[0].thread().unwrap().grip_of(1) else {
            slipped = Some(tick);
            break;
        };
        most_pull_n = most_pull_n.max(held.pull_n().norm());
        if tick % sinew_server::sim::KNOT_PERIOD_TICKS as usize == 0 {
            readings.push(out[0].suture.knot);
        }
    }
    let slack_mm = slack(d.nodes(), grip.node as usize);
    println!(
        "a laid knot drawn tight: {} readings {readings:?}, pull at the jaws up to {most_pull_n:.2} N \
         (slipped out at tick {slipped:?}), thread beyond the straight line between the hands \
         {slack_laid_mm:.1} -> {slack_mm:.1} mm, {passed_through} pairs passed through each other",
        readings.len()
    );
    assert_eq!(passed_through, 0, "the thread passed through itself");
    assert!(
        readings.len() >= 50
            && readings
                .iter()
                .all(|k| matches!(k, KnotKind::Throws(t) if *t == laid_knot)),
        "the knot came undone as it was drawn tight: {readings:?}"
    );
    assert!(
        most_pull_n > 1.0,
        "the jaws never felt the knot: {most_pull_n} N"
    );
    assert!(
        slack_mm < 0.5 * slack_laid_mm,
        "the knot did not tighten: {slack_laid_mm} -> {slack_mm} mm"
    );
}

/// The thread laid across its own needle (`thread_needle.rs`): from the tail it runs 3 mm up and 10 mm to one
/// side of the needle's plane, back across the wire 0.6 mm above it at `at_deg` along the arc, and down the
/// other side, 60 mm. It falls onto the wire and slides off it (the wire has no friction, and the thread's
/// weight draws it toward the tail). Over `ticks` ticks: the least distance from a segment (but the first,
/// swaged into the tail) to the arc, less the needle's radius plus the thread's (negative: inside the wire), and
/// the ticks a segment rested on the wire (within 0.05 mm of that clearance).
fn drape_over_the_needle(at_deg: f32, ticks: usize) -> (f32, u32) {
    let (mut d, origin, level) = hanging_driver();
    let tool = &d.sim.tools[0];
    let pose = *tool.needle_hold().unwrap().world_from_needle();
    let arc = *tool.needle().unwrap().arc();
    let (_, spec) = suture_block();
    let reach_mm = 0.5 * spec.diameter_mm + 0.5 * THREAD_DIAMETER_MM;
    let over = arc.at(at_deg.to_radians()).point_mm;
    let over_mm = (pose * Point3::from(over * (1.0 + (reach_mm + 0.6) / arc.radius_mm()))).coords;
    let across = pose.rotation * Vector3::z();
    let tail = d.tail_now();
    let path = [
        tail,
        tail + Vector3::new(0.0, 0.0, 3.0) - across * 10.0,
        over_mm - across * 10.0,
        over_mm + across * 10.0,
        over_mm + across * 12.0 - Vector3::new(0.0, 0.0, 60.0),
    ];
    assert!(d.sim.tools[0].thread_mut().unwrap().lay_along(&path));
    // The least distance from segment `a b` to the arc of the needle at `pose` (world; the driver sways a
    // little in its coupling as the thread swings), sampled every 1/40 of the segment.
    let to_arc = |pose: &Isometry3<f32>, a: &Vector3<f32>, b: &Vector3<f32>| {
        (0..=40)
            .map(|k| {
                let p =
                    pose.inverse_transform_point(&Point3::from(a + (b - a) * (k as f32 / 40.0)));
                (p.coords - arc.offset_of(&p.coords).nearest.point_mm).norm()
            })
            .fold(f32::INFINITY, f32::min)
    };
    let (mut least_mm, mut resting_ticks) = (f32::INFINITY, 0);
    for _ in 0..ticks {
        d.step(&origin, &level);
        let pose = *d.sim.tools[0].needle_hold().unwrap().world_from_needle();
        let n = d.nodes();
        let clear_mm = (1..n.len() - 1)
            .map(|i| to_arc(&pose, &n[i], &n[i + 1]))
            .fold(f32::INFINITY, f32::min)
            - reach_mm;
        least_mm = least_mm.min(clear_mm);
        if clear_mm < 0.05 {
            resting_ticks += 1;
        }
    }
    (least_mm, resting_ticks)
}

/// A thread draped over its own needle, at three places along the arc past the jaws: it rests on the wire for
/// at least 20 ticks and never ends a tick more than 0.02 mm inside it (measured 60-85 ticks, at worst 0.003 mm
/// inside; without the wire's contact it falls straight through, never resting on it).
#[test]
fn a_thread_draped_over_its_needle_rests_on_it_and_never_passes_through() {
    for at_deg in [60.0, 75.0, 90.0] {
        let (least_mm, resting_ticks) = drape_over_the_needle(at_deg, 300);
        println!(
            "a thread draped over its needle at {at_deg} degrees: rested on it {resting_ticks} ticks, closest \
             {least_mm:.4} mm from the wire"
        );
        assert!(
            least_mm > -0.02,
            "at {at_deg} degrees a segment came {} mm inside the wire",
            -least_mm
        );
        assert!(
            resting_ticks >= 20,
            "at {at_deg} degrees the thread rested on its needle only {resting_ticks} ticks"
        );
    }
}

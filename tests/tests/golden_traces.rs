//! Golden traces: the safety net of the server core's redesign (issue 30). Every shipped world runs with the
//! demo's two scripted surgeons (grasps, cuts, snips and burns where the world has those instruments) on the
//! drill's virtual time: the real server tick, the real device loops, no network. Every tool output, every
//! force command, every force rendered to a hand and the final state of every object are hashed, and the
//! hashes must equal the ones committed in `tests/golden/traces.txt`, to the bit. Two variants add what no
//! shipped world has: a grasped pull that tears, and a stroke with friction.
//!
//! A deliberate change of behaviour re-blesses the file (`SINEW_BLESS_GOLDEN=1 cargo test --release --test
//! golden_traces`) in a commit of its own that says why. A failure names the part that moved and the first
//! second of virtual time whose running hash differs.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use hapticserver::{HandPreset, ModePolicy, TraceSample};
use sinew_protocol::{ForceCommand, InstanceId, encode};
use sinew_server::server_tick::ServerTick;
use sinew_server::sim::ToolOutput;
use sinew_server::world::{InstrumentSpec, World};
use sinew_testkit::drill::{DrillDevice, Link, run_drill_observed};
use sinew_testkit::harness::{surgeon_scripts_for, worlds_dir};

/// Virtual time each world runs: long enough for every demo script's whole act (a grasp-pull releases at
/// 4.3 s, ten snips end at 5 s).
const DURATION_S: f64 = 5.5;

/// Worlds stepped every tick by finite elements cost milliseconds a tick: a shorter run still covers press,
/// stroke and release.
const HEAVY_DURATION_S: f64 = 2.5;

/// The committed hashes.
fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden/traces.txt")
}

/// FNV-1a, 64 bits: stable across platforms and Rust versions (std's hashers promise neither).
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f32(&mut self, x: f32) {
        self.bytes(&x.to_bits().to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.bytes(&x.to_bits().to_le_bytes());
    }
    fn u64(&mut self, x: u64) {
        self.bytes(&x.to_le_bytes());
    }
    fn vec3(&mut self, v: impl Into<[f32; 3]>) {
        for x in v.into() {
            self.f32(x);
        }
    }
}

/// Every field of a tool output, in a fixed order (a field that moves in the redesign keeps its place here).
fn hash_output(h: &mut Fnv, out: &ToolOutput) {
    h.vec3(out.force_world_n);
    h.u64(u64::from(out.held_nodes));
    h.u64(u64::from(out.in_contact) | u64::from(out.clamped) << 1);
    h.vec3(out.position_world_mm);
    h.vec3(out.velocity_world_mm_s);
    h.vec3(out.device_world_mm);
    h.vec3(out.device_velocity_world_mm_s);
    for x in out.stiffness_n_per_mm.iter() {
        h.f32(*x);
    }
    for x in out.damping_n_s_per_mm.iter() {
        h.f32(*x);
    }
    h.u64(u64::from(out.plane_count));
    for plane in &out.planes[..usize::from(out.plane_count)] {
        h.vec3(plane.normal);
        h.f32(plane.offset_mm);
        h.f32(plane.stiffness_n_per_mm);
        h.f32(plane.damping_n_s_per_mm);
    }
    h.f32(out.energy_allowance_mj);
    h.u64(u64::from(out.jaws_closed) | u64::from(out.burning) << 1 | u64::from(out.cutting) << 2);
    h.f32(out.jaw_angle_rad);
    h.u64(u64::from(out.attachments));
}

fn hash_sample(h: &mut Fnv, s: &TraceSample) {
    h.f64(s.t_s);
    h.vec3(s.position_mm);
    h.vec3(s.velocity_mm_s);
    h.vec3(s.force_n);
    h.f32(s.model_weight);
    h.u64(u64::from(s.stale));
    h.vec3(s.target_n);
    h.vec3(s.blend_offset_n);
    h.f64(s.passivity_energy_mj);
}

/// Every object's positions, velocities, burn, topology (triangles and split vertices' parents).
fn hash_state(h: &mut Fnv, server: &ServerTick) {
    for object in &server.sim().objects {
        h.bytes(object.name.as_bytes());
        for v in object
            .state
            .positions_mm
            .iter()
            .chain(&object.state.velocities_mm_s)
        {
            h.vec3(*v);
        }
        for b in object.burn() {
            h.bytes(&b.to_le_bytes());
        }
        h.u64(u64::from(object.topology_version()));
        let (first, parents) = object.split_parents();
        h.u64(u64::from(first));
        for p in parents {
            h.u64(u64::from(*p));
        }
        for t in object.model.triangles() {
            for i in t {
                h.u64(u64::from(*i));
            }
        }
    }
}

/// One world's hashes.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Golden {
    ticks: usize,
    outputs: u64,
    commands: u64,
    devices: u64,
    state: u64,
    /// The running hash of outputs and commands at the end of each whole second.
    seconds: Vec<u64>,
}

impl Golden {
    fn line(&self, name: &str) -> String {
        let seconds: Vec<String> = self.seconds.iter().map(|h| format!("{h:016x}")).collect();
        format!(
            "{name} ticks={} outputs={:016x} commands={:016x} devices={:016x} state={:016x} seconds={}",
            self.ticks,
            self.outputs,
            self.commands,
            self.devices,
            self.state,
            seconds.join(",")
        )
    }

    fn parse(line: &str) -> Option<(String, Self)> {
        let mut words = line.split_whitespace();
        let name = words.next()?.to_owned();
        let mut fields = BTreeMap::new();
        for word in words {
            let (key, value) = word.split_once('=')?;
            fields.insert(key, value);
        }
        let hex = |key: &str| u64::from_str_radix(fields.get(key)?, 16).ok();
        Some((
            name,
            Self {
                ticks: fields.get("ticks")?.parse().ok()?,
                outputs: hex("outputs")?,
                commands: hex("commands")?,
                devices: hex("devices")?,
                state: hex("state")?,
                seconds: fields
                    .get("seconds")?
                    .split(',')
                    .map(|h| u64::from_str_radix(h, 16).ok())
                    .collect::<Option<_>>()?,
            },
        ))
    }
}

/// Run `world` with its demo surgeons (nominal hands, direct mode, no delay) and hash everything.
fn trace(world: &World, duration_s: f64) -> (Golden, Vec<u32>) {
    let (left, right) = surgeon_scripts_for(world);
    let device = |id: &str, script| DrillDevice {
        id: id.to_owned(),
        hand: HandPreset::Nominal,
        script,
        link: Link::rtt(0.0),
        mode: ModePolicy::Direct,
    };
    let devices = [device("left", left), device("right", right)];
    let ticks = (duration_s * 1000.0).round() as usize;
    let (mut outputs, mut commands, mut state) = (Fnv::new(), Fnv::new(), Fnv::new());
    let mut running = Fnv::new();
    let mut seconds = Vec::new();
    let mut tick = 0usize;
    let mut bytes = Vec::new();
    let mut topology_versions = Vec::new();
    let result = run_drill_observed(
        world,
        &devices,
        duration_s,
        |server: &ServerTick, sent: &[Option<ForceCommand>]| {
            tick += 1;
            for out in server.outputs() {
                hash_output(&mut outputs, out);
                hash_output(&mut running, out);
            }
            for command in sent {
                match command {
                    Some(command) => {
                        encode(InstanceId(1), command, &mut bytes);
                        commands.bytes(&bytes);
                        running.bytes(&bytes);
                    }
                    None => commands.u64(0),
                }
            }
            if tick.is_multiple_of(1000) {
                seconds.push(running.0);
            }
            if tick == ticks {
                hash_state(&mut state, server);
                topology_versions = server
                    .sim()
                    .objects
                    .iter()
                    .map(|o| o.topology_version())
                    .collect();
            }
        },
    )
    .unwrap();
    assert_eq!(tick, ticks);
    let mut devices = Fnv::new();
    for trace in &result.traces {
        for sample in trace {
            hash_sample(&mut devices, sample);
        }
    }
    let golden = Golden {
        ticks,
        outputs: outputs.0,
        commands: commands.0,
        devices: devices.0,
        state: state.0,
        seconds,
    };
    (golden, topology_versions)
}

/// The committed hashes by world; a blessing run collects the new ones here and rewrites the file at exit.
static BLESSED: Mutex<BTreeMap<String, String>> = Mutex::new(BTreeMap::new());

fn committed() -> BTreeMap<String, Golden> {
    let text = std::fs::read_to_string(golden_path()).unwrap_or_default();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| Golden::parse(l).unwrap_or_else(|| panic!("unreadable golden line: {l}")))
        .collect()
}

/// Compare `name`'s run with its committed hashes (or, blessing, write them); the run's hashes and each
/// object's final topology version.
fn check(name: &str, world: &World, duration_s: f64) -> (Golden, Vec<u32>) {
    let (golden, topology_versions) = trace(world, duration_s);
    if std::env::var_os("SINEW_BLESS_GOLDEN").is_some() {
        let mut blessed = BLESSED.lock().unwrap();
        let mut all: BTreeMap<String, String> = committed()
            .into_iter()
            .map(|(n, g)| (n.clone(), g.line(&n)))
            .collect();
        blessed.insert(name.to_owned(), golden.line(name));
        all.extend(blessed.clone());
        let mut text = String::from(
            "# Golden traces (tests/tests/golden_traces.rs): FNV-1a hashes of each world's demo run on virtual time.\n\
             # Re-bless only for a deliberate change of behaviour, in a commit of its own that says why.\n",
        );
        for line in all.values() {
            text.push_str(line);
            text.push('\n');
        }
        std::fs::create_dir_all(golden_path().parent().unwrap()).unwrap();
        std::fs::write(golden_path(), text).unwrap();
        return (golden, topology_versions);
    }
    let Some(expected) = committed().remove(name) else {
        panic!(
            "no golden hashes for `{name}` in {}: bless them with SINEW_BLESS_GOLDEN=1",
            golden_path().display()
        );
    };
    if golden != expected {
        let first_second = golden
            .seconds
            .iter()
            .zip(&expected.seconds)
            .position(|(a, b)| a != b);
        let moved: Vec<&str> = [
            ("tool outputs", golden.outputs != expected.outputs),
            ("force commands", golden.commands != expected.commands),
            (
                "forces rendered to the hands",
                golden.devices != expected.devices,
            ),
            ("final object state", golden.state != expected.state),
            ("run length", golden.ticks != expected.ticks),
        ]
        .into_iter()
        .filter_map(|(what, differs)| differs.then_some(what))
        .collect();
        panic!(
            "`{name}` left its golden trace: {} differ; outputs and commands first differ in second {:?} of \
             virtual time.\n now:      {}\n expected: {}",
            moved.join(", "),
            first_second.map(|s| s + 1),
            golden.line(name),
            expected.line(name)
        );
    }
    (golden, topology_versions)
}

fn shipped(file: &str) -> World {
    sinew_testkit::harness::load_shipped_world(file).unwrap()
}

/// Every `.toml` under `worlds/` that is a world has a test below (the material presets are a library).
#[test]
fn every_shipped_world_has_a_golden_trace() {
    let covered = [
        "cautery",
        "cholecystectomy",
        "cut",
        "cut_under_tension",
        "exercise_accurate_touch",
        "exercise_coordination",
        "exercise_pattern_cutting",
        "exercise_stiffness_ranking",
        "fem_block",
        "grasp_pull",
        "liver",
        "liver_incision",
        "pad",
        "pad_stiff",
        "suture",
        "suture_block",
        "tet_block",
        "tug_of_war",
    ];
    for entry in std::fs::read_dir(worlds_dir()).unwrap() {
        let path = entry.unwrap().path();
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if path.extension().is_some_and(|e| e == "toml") && stem != "material_presets" {
            assert!(
                covered.contains(&stem),
                "worlds/{stem}.toml has no golden trace"
            );
        }
    }
}

macro_rules! golden_world {
    ($test:ident, $file:literal, $duration:expr) => {
        #[test]
        fn $test() {
            check(stringify!($test), &shipped($file), $duration);
        }
    };
}

golden_world!(pad, "pad.toml", DURATION_S);
golden_world!(pad_stiff, "pad_stiff.toml", DURATION_S);
golden_world!(cautery, "cautery.toml", DURATION_S);
golden_world!(cut, "cut.toml", DURATION_S);
golden_world!(cut_under_tension, "cut_under_tension.toml", DURATION_S);
golden_world!(grasp_pull, "grasp_pull.toml", DURATION_S);
golden_world!(
    exercise_accurate_touch,
    "exercise_accurate_touch.toml",
    DURATION_S
);
golden_world!(
    exercise_coordination,
    "exercise_coordination.toml",
    DURATION_S
);
golden_world!(
    exercise_stiffness_ranking,
    "exercise_stiffness_ranking.toml",
    DURATION_S
);
golden_world!(
    exercise_pattern_cutting,
    "exercise_pattern_cutting.toml",
    DURATION_S
);
golden_world!(tet_block, "tet_block.toml", DURATION_S);
golden_world!(fem_block, "fem_block.toml", HEAVY_DURATION_S);
golden_world!(liver, "liver.toml", DURATION_S);
golden_world!(cholecystectomy, "cholecystectomy.toml", DURATION_S);

/// The liver stepped on its own thread, cut by the demo's scalpel while the grasper pulls: the trace covers the
/// cut carried into the organ's step at a hand-off.
#[test]
fn liver_incision() {
    let (_, topology_versions) = check(
        "liver_incision",
        &shipped("liver_incision.toml"),
        DURATION_S,
    );
    assert!(
        topology_versions.first().is_some_and(|&v| v > 0),
        "the scalpel never cut the liver: topology versions {topology_versions:?}"
    );
}
golden_world!(tug_of_war, "tug_of_war.toml", DURATION_S);
golden_world!(suture_block, "suture_block.toml", DURATION_S);
golden_world!(suture, "suture.toml", DURATION_S);

/// The grasp-pull with a tissue that tears at 25% strain and jaws that do not slip first: the pull tears it.
#[test]
fn grasp_pull_tearing() {
    let mut world = shipped("grasp_pull.toml");
    let tissue = &mut world.objects[0].material;
    assert_eq!(
        tissue.tear_strain, None,
        "grasp_pull's tissue already tears"
    );
    tissue.tear_strain = Some(0.25);
    for tool in &mut world.tools {
        let InstrumentSpec::Grasper(grasp) = &mut tool.instrument else {
            panic!("grasp_pull's `{}` is not a grasper", tool.name);
        };
        assert_eq!(
            grasp.slip_force_n, 0.3,
            "grasp_pull's `{}` slip force",
            tool.name
        );
        grasp.slip_force_n = 20.0;
    }
    let (_, topology_versions) = check("grasp_pull_tearing", &world, DURATION_S);
    assert!(
        topology_versions.iter().any(|&v| v > 0),
        "the pull never tore the tissue: the variant tests nothing"
    );
}

/// The pad stroked with Coulomb friction: its run differs from the frictionless pad's.
#[test]
fn pad_friction() {
    let mut world = shipped("pad.toml");
    let tissue = &mut world.objects[0].material;
    assert_eq!(
        tissue.friction_coefficient, 0.0,
        "the pad already has friction"
    );
    tissue.friction_coefficient = 0.5;
    let (golden, _) = check("pad_friction", &world, DURATION_S);
    let (plain, _) = trace(&shipped("pad.toml"), DURATION_S);
    assert_ne!(golden.outputs, plain.outputs, "friction changed nothing");
}

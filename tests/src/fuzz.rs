//! Generated bad input, at scale (issue "Labs and sites"): every wire decoder, the world loader (and the
//! simulation built from what it accepts) and the recording reader (and the replay of what it accepts) are fed
//! mutated copies of valid inputs; each must answer with a value or an error, never a panic.
//!
//! Owns: the mutators (bytes: bit flips, interesting bytes, truncation, insertion, removal, duplication, varint
//! bombs; text: numbers replaced by extreme values, lines deleted, duplicated, swapped or garbled) and the
//! three targets, each counting inputs, accepted, refused and crashes (a caught panic, with the input that made
//! it). `cargo bench -p sinew-testkit --bench fuzz` runs millions; `tests/tests/fuzz_corpus.rs` a short run of each.
//!
//! Must not: touch the network, or leave files outside the directory it is given.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::*;
use sinew_server::recording::{
    FinalState, Recorder, TickRecord, read_recording, replay as replay_recording,
};
use sinew_server::server_tick::DeadbandParams;
use sinew_server::server_tick::{PoseInput, ServerTick};
use sinew_server::sim::Sim;
use sinew_server::world::parse_world;

/// What one target saw.
#[derive(Debug, Clone, Default)]
pub struct TargetReport {
    /// The target.
    pub name: &'static str,
    /// Inputs tried.
    pub inputs: u64,
    /// Inputs accepted (a value came back).
    pub accepted: u64,
    /// Inputs refused with an error.
    pub refused: u64,
    /// Panics caught, with the input that made each (the first 5), as text.
    pub crashes: Vec<String>,
    /// Panics caught in all.
    pub crash_count: u64,
}

impl TargetReport {
    fn new(name: &'static str) -> Self {
        Self {
            name,
            ..Self::default()
        }
    }

    /// Count one input's outcome (accepted, refused, or a panic described by `describe(message)`).
    fn tally(&mut self, outcome: Result<bool, String>, describe: impl FnOnce(&str) -> String) {
        self.inputs += 1;
        match outcome {
            Ok(true) => self.accepted += 1,
            Ok(false) => self.refused += 1,
            Err(message) => self.crash(describe(&message)),
        }
    }

    fn crash(&mut self, what: String) {
        self.crash_count += 1;
        if self.crashes.len() < 5 {
            self.crashes.push(what);
        }
    }
}

/// Run `f` with panics caught and their messages silenced; Err(message) on a panic.
fn guarded<R>(f: impl FnOnce() -> R) -> Result<R, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|payload| {
        payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_owned())
    })
}

/// A panic hook, as `std::panic::take_hook` returns it.
type PanicHook = Box<dyn Fn(&std::panic::PanicHookInfo<'_>) + Sync + Send + 'static>;

/// Silence the panic hook while fuzzing (each caught panic would print a backtrace); restored on drop. The hook
/// is the process's: run one target at a time.
struct QuietPanics(Option<PanicHook>);

impl QuietPanics {
    fn new() -> Self {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        Self(Some(previous))
    }
}

impl Drop for QuietPanics {
    fn drop(&mut self) {
        if let Some(previous) = self.0.take() {
            std::panic::set_hook(previous);
        }
    }
}

/// Valid payloads of every message kind: the mutators' seeds.
pub fn message_seeds() -> Vec<Vec<u8>> {
    let sender = InstanceId(0x0123_4567_89ab_cdef);
    let pose = DevicePose {
        seq: 300,
        device_time_ns: 1_000_000,
        position_mm: [1.0, 2.0, -3.5],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        render_mode: RenderMode::Moderated,
        ..DevicePose::default()
    };
    let mut planes = [ContactPlane::default(); MAX_CONTACT_PLANES];
    planes[0].normal = [0.0, 0.0, 1.0];
    let model = LocalModel {
        radius_mm: 2.0,
        fade_mm: 0.5,
        stiffness_n_per_mm: [0.0, 0.0, 0.25, 0.0, 0.0, 0.0],
        planes,
        plane_count: 1,
        ..LocalModel::default()
    };
    let tools = ToolStates {
        frame: 3,
        sim_time_s: 0.25,
        tools: vec![ToolState {
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..ToolState::default()
        }],
        threads: vec![ThreadState {
            holes: vec![sinew_protocol::HoleMark {
                position_mm: [0.0, 2.0, 0.0],
                pull_n: 1.0,
                on_needle: true,
            }],
            ..ThreadState::from_nodes_mm(0, &[[0.0, 0.0, 1.0], [0.0, 2.0, 1.0], [0.0, 4.0, 0.5]])
        }],
        needles: vec![sinew_protocol::NeedleState {
            tool: 0,
            position_mm: [0.0, 0.0, 3.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        }],
    };
    vec![
        encode_to_vec(sender, &pose),
        encode_to_vec(
            sender,
            &ForceCommand {
                seq: 7,
                force_n: [0.0, 0.0, 1.5],
                ..ForceCommand::default()
            },
        ),
        encode_to_vec(
            sender,
            &ForceCommand {
                mode: ForceMode::LocalModel(model),
                ..ForceCommand::default()
            },
        ),
        encode_to_vec(
            sender,
            &ParticipantHello {
                participant_id: "left".into(),
                role: Role::Haptic,
                device_model: "Touch".into(),
                max_force_n: 3.3,
                tool: "left-probe".into(),
            },
        ),
        encode_to_vec(
            sender,
            &MeshDelta {
                object: 0,
                frame: 12,
                prev_frame: 11,
                indices: vec![5, 300],
                positions_q: vec![[1, 2, 3], [65535, 0, 32768]],
                burn_indices: vec![5],
                burn: vec![200],
                topology: Some(sinew_protocol::TopologyDelta {
                    epoch: 1,
                    first_vertex: 301,
                    parents: vec![5, 7],
                    retargeted: vec![2],
                    corners: vec![[5, 301, 302]],
                    first_triangle: 10,
                    added: vec![[301, 302, 7]],
                }),
            },
        ),
        encode_to_vec(sender, &tools),
        encode_to_vec(
            sender,
            &SceneSnapshot {
                scene: "pad".into(),
                frame: 3,
                objects: vec![ObjectSnapshot {
                    object: 0,
                    name: "pad".into(),
                    bounds: QuantBounds {
                        min_mm: [-1.0; 3],
                        max_mm: [1.0; 3],
                    },
                    triangles: vec![[0, 1, 2]],
                    positions_q: vec![[0; 3], [1; 3], [2; 3]],
                    frame: 3,
                    burn: vec![0, 128, 255],
                    topology_epoch: 2,
                    error_bound_mm: 0.0,
                }],
                tools: vec![ToolInfo {
                    tool: 0,
                    name: "probe".into(),
                    device_id: "left".into(),
                    shape: ToolShape::Capsule {
                        half_length_mm: 5.0,
                        radius_mm: 1.0,
                    },
                    instrument: sinew_protocol::InstrumentInfo::Grasper {
                        jaw_length_mm: 8.0,
                        open_angle_rad: 0.7,
                    },
                    shaft: None,
                }],
                tool_states: tools,
            },
        ),
        encode_to_vec(
            sender,
            &ServerStats {
                devices: vec![DeviceStats::default()],
                exercise: Some(ExerciseStats {
                    targets: vec![sinew_protocol::TargetMark {
                        at_mm: [0.0, 0.0, 0.0],
                        radius_mm: 3.0,
                        hit: false,
                    }],
                    ..ExerciseStats::default()
                }),
                ..ServerStats::default()
            },
        ),
    ]
}

/// Bytes worth trying in any position.
const INTERESTING: [u8; 8] = [0x00, 0x01, 0x7f, 0x80, 0xfe, 0xff, 0x3f, 0x40];

/// A mutated copy of `seed` in `out`: one to four byte-level changes. Most keep the envelope's first three
/// bytes (version and kind), so the bodies are what gets explored.
pub fn mutate_bytes(rng: &mut fastrand::Rng, seed: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(seed);
    for _ in 0..rng.usize(1..=4) {
        let len = out.len();
        match rng.u8(0..8) {
            0 if len > 0 => {
                let i = rng.usize(0..len);
                out[i] ^= 1 << rng.u8(0..8);
            }
            1 if len > 0 => {
                let i = rng.usize(0..len);
                out[i] = INTERESTING[rng.usize(0..INTERESTING.len())];
            }
            2 => out.truncate(rng.usize(0..=len)),
            3 => {
                let at = rng.usize(0..=len);
                let extra: Vec<u8> = (0..rng.usize(1..=8)).map(|_| rng.u8(..)).collect();
                out.splice(at..at, extra);
            }
            4 if len > 0 => {
                let a = rng.usize(0..len);
                let b = rng.usize(a..=len.min(a + 16));
                out.drain(a..b);
            }
            5 if len > 0 => {
                let a = rng.usize(0..len);
                let b = rng.usize(a..=len.min(a + 32));
                let copy = out[a..b].to_vec();
                let at = rng.usize(0..=out.len());
                out.splice(at..at, copy);
            }
            6 => {
                // A varint that never ends, or a huge length.
                let at = rng.usize(0..=len);
                let bomb = vec![0xff; rng.usize(1..=10)];
                out.splice(at..at, bomb);
            }
            _ => {
                let i = rng.usize(0..=len);
                out.insert(i, rng.u8(..));
            }
        }
    }
    if seed.len() >= 3 && out.len() >= 3 && rng.u8(0..10) < 8 {
        out[..3].copy_from_slice(&seed[..3]);
    }
}

/// Feed `n` mutated payloads to every decoder (each payload to all seven kinds).
pub fn fuzz_decoders(seed: u64, n: u64) -> TargetReport {
    let _quiet = QuietPanics::new();
    let mut rng = fastrand::Rng::with_seed(seed);
    let seeds = message_seeds();
    let mut report = TargetReport::new("wire decoders");
    let mut input = Vec::with_capacity(1024);
    for i in 0..n {
        if i % 16 == 0 {
            // Plain noise too.
            input.clear();
            input.extend((0..rng.usize(0..64)).map(|_| rng.u8(..)));
        } else {
            let pick = rng.usize(0..seeds.len());
            mutate_bytes(&mut rng, &seeds[pick], &mut input);
        }
        let outcome = guarded(|| {
            [
                decode::<DevicePose>(&input).is_ok(),
                decode::<ForceCommand>(&input).is_ok(),
                decode::<SceneSnapshot>(&input).is_ok(),
                decode::<MeshDelta>(&input).is_ok(),
                decode::<ToolStates>(&input).is_ok(),
                decode::<ServerStats>(&input).is_ok(),
                decode::<ParticipantHello>(&input).is_ok(),
            ]
            .iter()
            .any(|ok| *ok)
        });
        report.tally(outcome, |message| format!("{message}: {}", hex(&input)));
    }
    report
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A small world (a 6 x 6 grid sheet of 4 mm cells, two tools, fixed edges, an exercise) as TOML, its mesh
/// beside it in `dir`.
pub fn seed_world(dir: &Path) -> std::io::Result<String> {
    let mesh = sinew_server::world::grid_sheet(6, 6, 4.0);
    std::fs::write(
        dir.join("sheet.obj"),
        sinew_server::world::to_obj_text(&mesh, &["fuzz seed"]),
    )?;
    Ok(r#"scene = "fuzz"
[sim]
tick_hz = 1000
publish_hz = 60
pose_timeout_s = 0.1
[collision]
margin_mm = 2.0
[[objects]]
name = "sheet"
mesh = "sheet.obj"
units = "mm"
integrator = "symplectic-euler"
dt_s = 0.001
quant_margin_mm = 40.0
[objects.material]
mass_kg = 0.05
stiffness_n_per_mm = 0.015
damping_n_s_per_mm = 0.000003
anchor_stiffness_n_per_mm = 0.008
drag_per_s = 150.0
[[objects.fixed]]
kind = "plane"
point_mm = [-10.0, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
tolerance_mm = 0.01
[[tools]]
name = "left-probe"
device = "left"
shape = { kind = "sphere", radius_mm = 2.0 }
device_origin_in_world_mm = [-4.0, 0.0, 0.0]
max_force_n = 3.3
coupling = { stiffness_n_per_mm = 5.0, damping_n_s_per_mm = 0.02, max_speed_mm_s = 500.0 }
[[tools]]
name = "right-probe"
device = "right"
shape = { kind = "capsule", half_length_mm = 5.0, radius_mm = 1.0 }
device_origin_in_world_mm = [4.0, 0.0, 0.0]
max_force_n = 3.3
[exercise]
name = "fuzz"
kind = "coordination"
time_limit_s = 60.0
[[exercise.targets]]
at_mm = [0.0, 0.0, 0.0]
radius_mm = 3.0
tool = "left-probe"
"#
    .to_owned())
}

/// Values worth putting where a number was.
const NUMBERS: [&str; 14] = [
    "0",
    "-1",
    "1e30",
    "-1e30",
    "nan",
    "inf",
    "-inf",
    "1e-30",
    "65536",
    "4294967296",
    "0.0",
    "-0.0",
    "1e400",
    "\"x\"",
];

/// A mutated copy of a TOML text: one to three line-level changes.
pub fn mutate_text(rng: &mut fastrand::Rng, seed: &str) -> String {
    let mut lines: Vec<String> = seed.lines().map(str::to_owned).collect();
    for _ in 0..rng.usize(1..=3) {
        if lines.is_empty() {
            break;
        }
        let i = rng.usize(0..lines.len());
        match rng.u8(0..7) {
            0 | 1 => {
                // Replace one number in the line.
                let line = &lines[i];
                let spans: Vec<(usize, usize)> = number_spans(line);
                if let Some(&(a, b)) = spans.get(rng.usize(0..spans.len().max(1))) {
                    let value = NUMBERS[rng.usize(0..NUMBERS.len())];
                    lines[i] = format!("{}{value}{}", &line[..a], &line[b..]);
                }
            }
            2 => {
                lines.remove(i);
            }
            3 => {
                let copy = lines[i].clone();
                lines.insert(rng.usize(0..=lines.len()), copy);
            }
            4 => {
                let j = rng.usize(0..lines.len());
                lines.swap(i, j);
            }
            5 => {
                let mut bytes = lines[i].clone().into_bytes();
                if !bytes.is_empty() {
                    let k = rng.usize(0..bytes.len());
                    bytes[k] = b"=[]{}\"#,.x0"[rng.usize(0..11)];
                }
                lines[i] = String::from_utf8_lossy(&bytes).into_owned();
            }
            _ => {
                let cut = rng.usize(0..=lines[i].len());
                if lines[i].is_char_boundary(cut) {
                    lines[i].truncate(cut);
                }
            }
        }
    }
    lines.join("\n")
}

/// Byte spans of the numbers in a line.
fn number_spans(line: &str) -> Vec<(usize, usize)> {
    let bytes = line.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit()
            || (bytes[i] == b'-' && bytes.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric() && bytes[i - 1] != b'_') {
            let start = i;
            i += 1;
            while i < bytes.len()
                && (bytes[i].is_ascii_digit() || matches!(bytes[i], b'.' | b'e' | b'-' | b'+'))
            {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Feed `n` mutated worlds to the loader; build and step (50 ticks, the left probe pressing) the simulation of
/// each it accepts. `dir` holds the seed's mesh.
pub fn fuzz_world_loader(seed: u64, n: u64, dir: &Path) -> std::io::Result<TargetReport> {
    let text = seed_world(dir)?;
    let path = dir.join("fuzz.toml");
    let _quiet = QuietPanics::new();
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut report = TargetReport::new("world loader + sim");
    for _ in 0..n {
        let input = mutate_text(&mut rng, &text);
        let outcome = guarded(|| match parse_world(&path, &input) {
            Ok(world) => {
                if let Ok(sim) = Sim::new(&world) {
                    step_pressing(sim, world.tick_hz, world.pose_timeout_s, 50);
                }
                true
            }
            Err(_) => false,
        });
        report.tally(outcome, |message| format!("{message}:\n{input}"));
    }
    Ok(report)
}

/// Step `sim` `ticks` times with the first tool pressing 2 mm below its device origin.
fn step_pressing(sim: Sim, tick_hz: f64, pose_timeout_s: f64, ticks: u64) -> Vec<TickRecord> {
    let n = sim.tools.len();
    let mut tick = ServerTick::new(
        sim,
        (1.0 / tick_hz) as f32,
        pose_timeout_s,
        DeadbandParams::default(),
    );
    let mut inputs = vec![None; n];
    let limits = vec![None; n];
    let mut out = vec![None; n];
    let mut records = Vec::new();
    for k in 0..ticks {
        if let Some(first) = inputs.first_mut() {
            *first = Some(PoseInput {
                pose: DevicePose {
                    seq: k + 1,
                    position_mm: [0.0, 0.0, 2.0 - 4.0 * k as f32 / ticks as f32],
                    orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                    ..DevicePose::default()
                },
                age_s: 0.0,
                usable: true,
            });
        }
        tick.step(&inputs, &limits, &mut out);
        records.push(TickRecord::new(k, &inputs, &limits, &out));
    }
    records
}

/// Feed `n` mutated copies of a short recording of the seed world to the reader; replay each it accepts.
pub fn fuzz_recordings(seed: u64, n: u64, dir: &Path) -> anyhow::Result<TargetReport> {
    let text = seed_world(dir)?;
    let world_path = dir.join("fuzz.toml");
    std::fs::write(&world_path, &text)?;
    let world = sinew_server::world::load_world(&world_path)?;
    let original = dir.join("seed.mcap");
    let (recorder, mut tap) = Recorder::start(&original, &world)?;
    let records = step_pressing(Sim::new(&world)?, world.tick_hz, world.pose_timeout_s, 120);
    for record in &records {
        tap.offer(record);
        // The queue holds 256: never full at this length, but keep the writer in step anyway.
        std::thread::yield_now();
    }
    tap.finish(FinalState {
        ticks: records.len() as u64,
        positions_mm: Vec::new(),
    });
    let summary = recorder.join();
    anyhow::ensure!(
        summary.error.is_none(),
        "writing the seed recording: {summary:?}"
    );
    let bytes = std::fs::read(&original)?;
    let mutated = dir.join("mutated.mcap");
    let replay_dir = dir.join("replay-world");
    std::fs::create_dir_all(&replay_dir)?;
    let _quiet = QuietPanics::new();
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut report = TargetReport::new("recording reader + replay");
    let mut input = Vec::with_capacity(bytes.len() + 64);
    for _ in 0..n {
        mutate_bytes(&mut rng, &bytes, &mut input);
        std::fs::write(&mutated, &input)?;
        let outcome = guarded(|| match read_recording(&mutated) {
            Ok(recording) => {
                if let Ok(world) = recording.load_world(&replay_dir) {
                    let _ = replay_recording(&recording, &world);
                }
                true
            }
            Err(_) => false,
        });
        report.tally(outcome, |message| {
            format!("{message} ({} bytes)", input.len())
        });
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panicking_target_is_counted_as_a_crash() {
        // (The panic prints its message: the hook is the process's, and other tests run beside this one.)
        let caught = guarded(|| -> u8 { panic!("boom") });
        assert_eq!(caught, Err("boom".to_owned()));
        let mut report = TargetReport::new("t");
        report.crash("boom: 00".to_owned());
        assert_eq!(report.crash_count, 1);
    }

    #[test]
    fn mutations_stay_near_their_seed_and_text_mutations_replace_numbers() {
        let mut rng = fastrand::Rng::with_seed(9);
        let seed = message_seeds()[0].clone();
        let mut out = Vec::new();
        let mut differs = 0;
        for _ in 0..1000 {
            mutate_bytes(&mut rng, &seed, &mut out);
            differs += usize::from(out != seed);
            assert!(out.len() <= seed.len() + 4 * 64);
        }
        assert!(differs > 900, "{differs}");
        assert_eq!(
            number_spans("a = [1.5, -2e3], b_2 = 7"),
            vec![(5, 8), (10, 14), (23, 24)]
        );
    }
}

//! The ~60 Hz publish thread: mesh deltas, tool states, stats; and the snapshot queryable it feeds.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::rt::Pacer;
use sinew_protocol::{
    DeviceStats, ExerciseStats, MeshDelta, ServerStats, TargetMark, ToolStates, TrainingStats,
    encode,
};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

use super::{ServerError, Shared};
use crate::replication::ObjectReplication;
use crate::scene::{ExerciseKind, ExerciseSpec};
use crate::tissue::Vec3;
use crate::training::LiveScore;

/// Stats as published: sim report, replication counters, device slots, rejects.
pub(crate) fn build_stats(shared: &Shared) -> ServerStats {
    let mut stats = ServerStats {
        rejected: shared.rejects.snapshot(),
        server_id: shared.server_id.clone(),
        foreign_server_messages: shared.foreign_servers.foreign(),
        foreign_server_instance: shared.foreign_servers.last_foreign().0,
        ..ServerStats::default()
    };
    if let Ok(report) = shared.report.lock() {
        stats.sim_time_s = report.sim_time_s;
        stats.ticks = report.ticks;
        stats.tick_p50_us = report.tick_time.percentile_us(50.0);
        stats.tick_p99_us = report.tick_time.percentile_us(99.0);
        stats.tick_max_us = report.tick_time.max_ns() as f32 / 1000.0;
        stats.overruns = report.overruns;
        stats.sim_faults = report.faults;
        stats.devices = shared
            .slots
            .iter()
            .zip(&report.devices)
            .map(|(slot, d)| DeviceStats {
                device_id: slot.device_id.clone(),
                active: d.active,
                poses_received: slot.poses_received.load(Ordering::Relaxed),
                forces_sent: d.forces_sent,
                last_round_trip_us: d.last_round_trip_us,
                max_force_n: d.max_force_n,
                moderated: d.moderated,
                forces_suppressed: d.suppressed,
                tool: slot.tool_name.clone(),
                holder_instance: slot.holder().0,
                duplicates_refused: slot.duplicates_refused.load(Ordering::Relaxed),
                last_refused_instance: slot.last_duplicate.load(Ordering::Relaxed),
                wrong_tool_instance: slot.wrong_tool_instance.load(Ordering::Relaxed),
                wrong_tool_asked: slot
                    .wrong_tool_asked
                    .lock()
                    .map(|a| a.clone())
                    .unwrap_or_default(),
                force_limit_n: d
                    .force_limit_n
                    .or_else(|| slot.hello_max_force_n())
                    .unwrap_or(0.0),
                training: training_stats(&d.training),
            })
            .collect();
        stats.exercise = shared
            .world
            .exercise
            .as_ref()
            .zip(report.exercise.as_ref())
            .map(|(spec, live)| exercise_stats(spec, live));
    }
    if let Ok(replication) = shared.replication.lock() {
        stats.deltas_sent = replication.deltas_sent;
        stats.delta_bytes_sent = replication.delta_bytes;
        stats.snapshots_served = replication.snapshots_served;
        stats.quantization_clamps = replication
            .objects
            .iter()
            .map(ObjectReplication::clamped)
            .sum();
    }
    stats
}

/// The wire form of a participant's live training view.
pub fn training_stats(live: &super::LiveTraining) -> TrainingStats {
    TrainingStats {
        skill_state: live.state.name().to_owned(),
        contacts: live.contacts,
        contact_time_s: live.contact_time_s as f32,
        path_length_mm: live.path_length_mm as f32,
        peak_force_n: live.peak_force_n as f32,
        harm_n_s: live.harm_n_s as f32,
    }
}

/// The wire form of an exercise's running score, with its targets and which are hit (targets are hit in
/// order: the first `hits`; a ranking has samples, not targets; a pattern's marks are its two circles).
pub fn exercise_stats(spec: &ExerciseSpec, live: &LiveScore) -> ExerciseStats {
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    let hit_targets = if spec.kind == ExerciseKind::StiffnessRanking {
        0
    } else {
        live.hits
    };
    ExerciseStats {
        kind: spec.kind.as_str().to_owned(),
        score: live.score as f32,
        hits: count(live.hits),
        total: count(live.total),
        errors: live.errors.total(),
        time_s: live.time_s as f32,
        completed: live.completed,
        timed_out: live.timed_out,
        targets: match &spec.pattern {
            // A pattern's marks are its two circles, hit once the circle is cut free.
            Some(pattern) => [pattern.inner_radius_mm, pattern.outer_radius_mm]
                .map(|radius_mm| TargetMark {
                    at_mm: pattern.centre_mm,
                    radius_mm,
                    hit: live.completed,
                })
                .to_vec(),
            None => spec
                .targets
                .iter()
                .take(ExerciseStats::MAX_TARGETS)
                .enumerate()
                .map(|(i, target)| TargetMark {
                    at_mm: target.at_mm,
                    radius_mm: target.radius_mm,
                    hit: i < hit_targets,
                })
                .collect(),
        },
    }
}

pub(super) fn spawn(
    session: &zenoh::Session,
    shared: Arc<Shared>,
) -> Result<JoinHandle<()>, ServerError> {
    let mut delta_publishers = Vec::new();
    if let Ok(replication) = shared.replication.lock() {
        for object in &replication.objects {
            delta_publishers.push(
                session
                    .declare_publisher(shared.keys.mesh_delta(object.name())?)
                    .congestion_control(CongestionControl::Block)
                    .wait()?,
            );
        }
    }
    let tools_publisher = session
        .declare_publisher(shared.keys.tools())
        .congestion_control(CongestionControl::Drop)
        .wait()?;
    let stats_publisher = session.declare_publisher(shared.keys.stats()).wait()?;
    let s = shared.clone();
    let queryable = session
        .declare_queryable(shared.keys.snapshot())
        .callback(move |query| {
            let bytes = match s.replication.lock() {
                Ok(mut replication) => {
                    replication.snapshots_served += 1;
                    encode_to_vec(s.instance, &replication.snapshot(&s.world.scene))
                }
                Err(_) => return,
            };
            if let Err(e) = query.reply(s.keys.snapshot(), bytes).wait() {
                tracing::warn!("snapshot reply failed: {e}");
            }
        })
        .wait()?;
    std::thread::Builder::new()
        .name("sinew-publish".into())
        .spawn(move || {
            let _queryable = queryable;
            run(
                &shared,
                &delta_publishers,
                &tools_publisher,
                &stats_publisher,
            );
        })
        .map_err(|e| ServerError::Thread(e.to_string()))
}

fn run(
    shared: &Shared,
    delta_publishers: &[zenoh::pubsub::Publisher<'static>],
    tools_publisher: &zenoh::pubsub::Publisher<'static>,
    stats_publisher: &zenoh::pubsub::Publisher<'static>,
) {
    let mut pacer = Pacer::new(Duration::from_secs_f64(1.0 / shared.world.publish_hz), 0);
    let mut last_offered = 0;
    let mut objects = ObjectFrames::default();
    let mut tool_states = ToolStates::default();
    let mut delta = MeshDelta::default();
    let mut buf = Vec::with_capacity(64 * 1024);
    let mut last_stats = Instant::now();
    let mut late = super::tick_cost::LateTicks::new();
    let period_us = 1e6 / shared.world.tick_hz;

    while !shared.stop.load(Ordering::Acquire) {
        pacer.wait();
        let offered = shared.frames.offered();
        if offered != last_offered {
            last_offered = offered;
            let copied = shared.frames.with_frame(|frame| {
                objects.copy_from(frame);
                tool_states.sim_time_s = frame.sim_time_s;
                tool_states.tools.clear();
                tool_states.tools.extend_from_slice(&frame.tools);
                tool_states.threads.clone_from(&frame.threads);
                tool_states.needles.clone_from(&frame.needles);
            });
            if copied.is_some() {
                publish_frame(
                    shared,
                    &objects,
                    &mut tool_states,
                    &mut delta,
                    &mut buf,
                    delta_publishers,
                );
                encode(shared.instance, &tool_states, &mut buf);
                let _ = tools_publisher.put(buf.as_slice()).wait();
            }
        }
        if last_stats.elapsed() >= Duration::from_secs(1) {
            last_stats = Instant::now();
            let stats = build_stats(shared);
            if let Some(line) = late.observe(
                last_stats,
                stats.ticks,
                stats.overruns,
                stats.tick_p99_us,
                period_us,
            ) {
                tracing::warn!("{line}");
            }
            encode(shared.instance, &stats, &mut buf);
            let _ = stats_publisher.put(buf.as_slice()).wait();
        }
    }
}

/// The publish thread's copy of the objects in a frame (buffers reused from frame to frame).
#[derive(Debug, Default)]
struct ObjectFrames {
    positions: Vec<Vec<Vec3>>,
    burn: Vec<Vec<u8>>,
    topology: Vec<crate::replication::ObjectTopology>,
}

impl ObjectFrames {
    /// Copy `frame`'s objects in; a topology is copied only when a cut or tear changed it.
    fn copy_from(&mut self, frame: &crate::replication::FrameData) {
        self.positions
            .resize_with(frame.positions_mm.len(), Vec::new);
        for (dst, src) in self.positions.iter_mut().zip(&frame.positions_mm) {
            dst.clear();
            dst.extend_from_slice(src);
        }
        self.burn.resize_with(frame.burn.len(), Vec::new);
        for (dst, src) in self.burn.iter_mut().zip(&frame.burn) {
            dst.clear();
            dst.extend_from_slice(src);
        }
        self.topology
            .resize_with(frame.topology.len(), Default::default);
        for (dst, src) in self.topology.iter_mut().zip(&frame.topology) {
            dst.sync_from(src);
        }
    }
}

fn publish_frame(
    shared: &Shared,
    objects: &ObjectFrames,
    tool_states: &mut ToolStates,
    delta: &mut MeshDelta,
    buf: &mut Vec<u8>,
    delta_publishers: &[zenoh::pubsub::Publisher<'static>],
) {
    let Ok(mut replication) = shared.replication.lock() else {
        return;
    };
    replication.frame += 1;
    let frame = replication.frame;
    tool_states.frame = frame;
    replication.tool_states.clone_from(tool_states);
    for (o, (object_positions, publisher)) in
        objects.positions.iter().zip(delta_publishers).enumerate()
    {
        let object_burn = objects.burn.get(o).map_or(&[][..], |b| b.as_slice());
        if replication.objects[o].delta(
            o as u16,
            object_positions,
            object_burn,
            objects.topology.get(o),
            frame,
            delta,
        ) {
            encode(shared.instance, &*delta, buf);
            // Sent under the replication lock so a snapshot can never be taken between a delta's state
            // change and its publication.
            if publisher.put(buf.as_slice()).wait().is_ok() {
                replication.deltas_sent += 1;
                replication.delta_bytes += buf.len() as u64;
            }
        }
    }
}

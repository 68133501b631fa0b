//! Server stats: server -> anyone.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};

/// Inbound messages the server refused, by reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct RejectCounts {
    /// Too short, or a body that does not parse.
    pub malformed: u64,
    /// Another protocol version.
    pub wrong_version: u64,
    /// Parsed, but a field out of domain (NaN pose, non-unit quaternion).
    pub invalid: u64,
    /// A pose from a device no tool is bound to.
    pub unknown_device: u64,
    /// A pose from a second hapticserver using a device id another one holds.
    pub duplicate_device: u64,
    /// A pose from a device whose hello asked for another tool than the world binds to its id.
    pub wrong_tool: u64,
    /// A pose from a device instance whose hello has not arrived yet (a device must say hello first).
    pub no_hello: u64,
    /// Messages zenoh's access control dropped before they reached the server: a peer publishing where its
    /// certificate's role may not (an observer's pose, a device's pose for another id), or sent to a peer
    /// whose certificate names no role (only with TLS; `protocol::security`).
    pub access_denied: u64,
    /// TLS connections the server's listener refused: a peer without a certificate from the lab's CA (only
    /// with TLS).
    pub tls_refused: u64,
}

impl RejectCounts {
    /// Sum of all reasons.
    pub fn total(&self) -> u64 {
        self.malformed
            + self.wrong_version
            + self.invalid
            + self.unknown_device
            + self.duplicate_device
            + self.wrong_tool
            + self.no_hello
            + self.access_denied
            + self.tls_refused
    }
}

/// Per-device view from the server.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct DeviceStats {
    /// Device id.
    pub device_id: String,
    /// Poses arriving within the world's pose timeout from a device that is present and not refused: its
    /// tool is active.
    pub active: bool,
    /// Poses accepted.
    pub poses_received: u64,
    /// Forces published.
    pub forces_sent: u64,
    /// The device's last reported pose->force round trip, microseconds (0 = unknown).
    pub last_round_trip_us: u32,
    /// Largest force magnitude sent, newtons.
    pub max_force_n: f32,
    /// The device renders the local model (latency-moderated mode) rather than the streamed force.
    pub moderated: bool,
    /// Ticks on which the device's model stayed within the perceptual deadband and nothing was sent.
    pub forces_suppressed: u64,
    /// The tool the world binds to this device id.
    pub tool: String,
    /// The instance (envelope sender) holding the id: the first hapticserver whose pose arrived, until it
    /// leaves or goes quiet for the claim timeout. 0: nobody holds it.
    pub holder_instance: u64,
    /// Instances refused the id because another held it (each counted once).
    pub duplicates_refused: u64,
    /// The latest instance refused the id because another held it (0: none yet).
    pub last_refused_instance: u64,
    /// The latest instance refused because its hello asked for another tool (0: none), and that tool.
    pub wrong_tool_instance: u64,
    /// The tool that refused instance asked for.
    pub wrong_tool_asked: String,
    /// The force limit the holding device announced in its hello, newtons (0: no hello yet). What a viewer
    /// scales the force it draws against.
    pub force_limit_n: f32,
    /// The training layer's view of this participant (what an instructor watches).
    pub training: TrainingStats,
}

/// One participant as the training layer sees it, live (server -> anyone, in [`DeviceStats`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TrainingStats {
    /// Current surgical (skill) state: `idle`, `approach`, `contact`, `grasping`, `pulling`, `cutting`,
    /// `cauterizing`, `releasing`, and suturing's `needle_grasped`, `puncture`, `push_through`, `pull_through`,
    /// `tighten` (an unknown name is shown as it is).
    pub skill_state: String,
    /// Touches so far.
    pub contacts: u64,
    /// Time in contact, seconds.
    pub contact_time_s: f32,
    /// Instrument tip path, mm.
    pub path_length_mm: f32,
    /// Largest force on the tool, newtons.
    pub peak_force_n: f32,
    /// Force above the harm threshold, integrated, newton seconds.
    pub harm_n_s: f32,
}

/// The running exercise, scored live (server -> anyone, in [`ServerStats`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ExerciseStats {
    /// The exercise kind: `coordination`, `accurate-touch`, `stiffness-ranking`, `suture`, `pattern-cutting`.
    pub kind: String,
    /// Score so far, 0-100.
    pub score: f32,
    /// Targets hit (a ranking: pairs in the right order so far).
    pub hits: u32,
    /// Targets (a ranking: pairs).
    pub total: u32,
    /// Errors so far.
    pub errors: u32,
    /// Time on the exercise's clock, seconds.
    pub time_s: f32,
    /// Every target hit.
    pub completed: bool,
    /// The time limit passed.
    pub timed_out: bool,
    /// The exercise's targets (or a suture's marks, or a pattern's two circles about one centre) in order,
    /// with whether each is hit: a viewer marks them.
    /// Protocol 18.
    pub targets: Vec<TargetMark>,
}

/// One target of the running exercise, where the world file puts it. Protocol 18.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct TargetMark {
    /// Where it is marked on the tissue at rest, world mm.
    pub at_mm: [f32; 3],
    /// How close counts as on it, mm.
    pub radius_mm: f32,
    /// It has been hit.
    pub hit: bool,
}

impl ExerciseStats {
    /// Most targets one exercise may show.
    pub const MAX_TARGETS: usize = 256;
}

/// Server health, published at 1 Hz on `sinew/<scene>/stats`.
///
/// Direction: server -> anyone. Rate: 1 Hz. Reliability: best effort. Units: microseconds, bytes, seconds.
/// Tick percentiles cover the whole run so far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ServerStats {
    /// Simulated time, seconds.
    pub sim_time_s: f64,
    /// Sim ticks run.
    pub ticks: u64,
    /// Tick compute time, median, microseconds.
    pub tick_p50_us: f32,
    /// Tick compute time, 99th percentile, microseconds.
    pub tick_p99_us: f32,
    /// Tick compute time, maximum, microseconds.
    pub tick_max_us: f32,
    /// Ticks that started late by more than a whole period (VM stalls).
    pub overruns: u64,
    /// Steps in which the tissue produced a non-finite value and was restored.
    pub sim_faults: u64,
    /// Mesh delta messages published.
    pub deltas_sent: u64,
    /// Mesh delta bytes published.
    pub delta_bytes_sent: u64,
    /// Snapshot queries answered.
    pub snapshots_served: u64,
    /// Vertex positions that fell outside their object's quantization bounds and were clamped on the wire
    /// (should stay 0; otherwise raise the object's `quant_margin_mm`).
    pub quantization_clamps: u64,
    /// Refused inbound messages.
    pub rejected: RejectCounts,
    /// One entry per tool-bound device.
    pub devices: Vec<DeviceStats>,
    /// The server's id (its presence key segment).
    pub server_id: String,
    /// Stats messages heard from another server instance for this scene (two servers are live).
    pub foreign_server_messages: u64,
    /// The latest other server instance heard (0: none).
    pub foreign_server_instance: u64,
    /// The world's exercise, scored live (None: the world is not an exercise).
    pub exercise: Option<ExerciseStats>,
}

impl Message for ServerStats {
    const KIND: MessageKind = MessageKind::ServerStats;
    fn validate(&self) -> Result<(), FieldError> {
        check::finite(
            "tick_us",
            &[self.tick_p50_us, self.tick_p99_us, self.tick_max_us],
        )?;
        if !self.sim_time_s.is_finite() {
            return Err(("sim_time_s", "not finite"));
        }
        for device in &self.devices {
            let t = &device.training;
            check::finite(
                "devices.training",
                &[
                    device.force_limit_n,
                    t.contact_time_s,
                    t.path_length_mm,
                    t.peak_force_n,
                    t.harm_n_s,
                ],
            )?;
        }
        if let Some(exercise) = &self.exercise {
            check::finite("exercise", &[exercise.score, exercise.time_s])?;
            if exercise.targets.len() > ExerciseStats::MAX_TARGETS {
                return Err(("exercise.targets", "more than 256 targets"));
            }
            for target in &exercise.targets {
                check::finite("exercise.targets.at_mm", &target.at_mm)?;
                if !(target.radius_mm.is_finite() && target.radius_mm > 0.0) {
                    return Err(("exercise.targets.radius_mm", "not a positive finite number"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exercises_targets_must_be_finite_with_a_positive_radius() {
        let target = TargetMark {
            at_mm: [10.0, 0.0, 0.0],
            radius_mm: 3.0,
            hit: true,
        };
        let with = |targets: Vec<TargetMark>| ServerStats {
            exercise: Some(ExerciseStats {
                targets,
                ..ExerciseStats::default()
            }),
            ..ServerStats::default()
        };
        assert_eq!(with(vec![target]).validate(), Ok(()));
        for (bad, field) in [
            (
                TargetMark {
                    at_mm: [0.0, f32::NAN, 0.0],
                    ..target
                },
                "exercise.targets.at_mm",
            ),
            (
                TargetMark {
                    radius_mm: 0.0,
                    ..target
                },
                "exercise.targets.radius_mm",
            ),
            (
                TargetMark {
                    radius_mm: f32::NAN,
                    ..target
                },
                "exercise.targets.radius_mm",
            ),
        ] {
            assert!(
                matches!(with(vec![target, bad]).validate(), Err((f, _)) if f == field),
                "{bad:?}"
            );
        }
        assert!(matches!(
            with(vec![target; ExerciseStats::MAX_TARGETS + 1]).validate(),
            Err(("exercise.targets", _))
        ));
    }
}

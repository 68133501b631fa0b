//! The stream of force commands to one device: the local model in the device frame, and when to send it.
//!
//! Owns: [`ModelStream`] (per device: the last model sent, the sequence number, counters) and
//! [`DeadbandParams`]. Every tick [`ModelStream::command`] turns the tool's [`ToolOutput`] into a
//! [`ForceCommand`] carrying both the direct force (the tissue's force on the tool, as a virtual coupling
//! renders it) and the model
//! itself, and decides whether it is worth sending:
//! - a device rendering directly gets every tick's command (its force is only as fresh as the last message);
//! - a device rendering the model gets one only when the model changed perceptibly, and at least every
//!   [`DeadbandParams::heartbeat_s`]. "Perceptibly": the new `f0` differs from what the last model sent
//!   predicts at the new `x0` by more than the Weber fraction (5% of the force; force discrimination
//!   thresholds are 5-10%, Jones 1989, Pang, Tan & Durlach 1991; Hinterseer et al. 2008 cut haptic packet
//!   rates by ~90% with such a deadband and no perceived difference) or an absolute 10 mN floor (below the
//!   hand's detection threshold for force changes of a few tens of mN); or `K` moved by 10%; or a plane moved
//!   by 0.05 mm or turned by 1 degree; or the contact began or ended; or a grasp took hold or let go
//!   (`attached`); or the drag of cutting moved by the Weber fraction or the floor; or the friction
//!   coefficient changed or the stick spring moved by 10%; or the energy allowance moved by 0.5 mJ.
//!   The heartbeat (7 ms, 143 messages/s) keeps a still hand's stream inside the device's 50 ms silence rule
//!   on a jittery path: with `k` messages lost in a row the device waits at most `(k + 1) * 7 ms` plus the
//!   path's peak-to-peak jitter, so with 20 ms of jitter (+-10 ms) a false silence needs four losses in a row
//!   (at 5% loss, at most about once in 20 minutes; at 1%, once in months). That is the envelope: at +-20 ms
//!   one loss with late jitter reaches the rule, 16 times an hour of holding at 5% loss
//!   (`tests/tests/heartbeat_envelope.rs` measures both). An 11 ms heartbeat (91/s) reached the rule
//!   with two losses and late jitter: 2.4% of 6 s holds through 50 +- 10 ms and 5% loss, by simulation, and
//!   once in CI (tests/netns_lab).
//!
//! Must not: touch the network (the node publishes what this returns) or allocate.

use nalgebra::Matrix3;
use sinew_protocol::{
    ContactPlane, DevicePose, ForceCommand, ForceMode, LocalModel, MAX_CONTACT_PLANES,
    MAX_FRICTION_COEFFICIENT, PunctureTerm, RenderMode, Sym3,
};

use crate::haptics::contact_stiffness::psd_part;
use crate::sim::{NeedlePop, ToolOutput};
use crate::tissue::Vec3;

/// Slack on the heartbeat period, s: a tenth of a 1 kHz tick.
const HEARTBEAT_TOLERANCE_S: f64 = 1e-4;

/// When a device in latency-moderated mode is sent a new model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeadbandParams {
    /// Relative force change that is sent, of |f0|.
    pub weber_fraction: f32,
    /// Absolute force change that is always sent, N.
    pub force_floor_n: f32,
    /// Relative change of `K` (Frobenius) that is sent.
    pub stiffness_fraction: f32,
    /// Plane offset change that is sent, mm.
    pub plane_offset_mm: f32,
    /// Plane normal change that is sent: cosine of the angle.
    pub plane_normal_cos: f32,
    /// Allowance change that is sent, mJ.
    pub allowance_mj: f32,
    /// Longest time between two messages, s.
    pub heartbeat_s: f64,
}

impl Default for DeadbandParams {
    fn default() -> Self {
        Self {
            weber_fraction: 0.05,
            force_floor_n: 0.01,
            stiffness_fraction: 0.1,
            plane_offset_mm: 0.05,
            plane_normal_cos: 0.999_85, // 1 degree
            allowance_mj: 0.5,
            heartbeat_s: 0.007,
        }
    }
}

/// Validity radius of a model around its `x0` for a hand at rest, mm, and the width of its fade, mm.
///
/// A moving hand gets a larger radius: [`ModelStream`] adds the distance the hand may travel before the next
/// model reaches it (its recent peak speed times its round trip plus the heartbeat), up to
/// [`MAX_MODEL_RADIUS_MM`]. A model that fades out under a hand stroking at 100 mm/s 100 ms away (10 mm from
/// `x0` when it is rendered) renders nothing: at 2 Hz the force fell to zero for most of each stroke. The
/// linear part is one-sided along the contact normal and its `K` has no tangential part (a frictionless tool
/// drags its dent along: the field is translation invariant), so along the surface the model holds as far as
/// the surface stays flat; past an edge it may render the surface on for at most one round trip.
pub const MODEL_RADIUS_MM: f32 = 8.0;
/// The largest validity radius, mm: a 200 ms round trip at 150 mm/s.
pub const MAX_MODEL_RADIUS_MM: f32 = 40.0;
/// The peak speed a stream sizes its radius from decays with this time constant, s (a stroke's turn-around,
/// at 1-2 Hz, does not shrink it).
pub const REACH_SPEED_MEMORY_S: f64 = 0.5;
/// See [`MODEL_RADIUS_MM`].
pub const MODEL_FADE_MM: f32 = 3.0;

/// What a stream has done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamCounters {
    /// Commands sent.
    pub sent: u64,
    /// Ticks on which a moderated device's model was within the deadband and nothing was sent.
    pub suppressed: u64,
    /// Of `sent`, the moderated heartbeats: models sent only because [`DeadbandParams::heartbeat_s`] had passed
    /// since the last one, nothing in them differing perceptibly (a still hand's whole stream).
    pub heartbeats: u64,
}

/// Why a moderated device gets this tick's model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SendReason {
    /// Something in the model differs perceptibly from what the device renders.
    Change,
    /// Nothing does, but the heartbeat period has passed.
    Heartbeat,
}

/// The command stream to one device.
#[derive(Debug, Clone)]
pub struct ModelStream {
    params: DeadbandParams,
    origin_world_mm: Vec3,
    last_sent: Option<LocalModel>,
    last_sent_s: f64,
    seq: u64,
    counters: StreamCounters,
    /// The device's recent peak speed (decaying), mm/s, and when it was last updated, s.
    reach_speed_mm_s: f32,
    reach_updated_s: f64,
}

fn sym3(m: &Matrix3<f32>) -> Sym3 {
    [
        m[(0, 0)],
        m[(1, 1)],
        m[(2, 2)],
        0.5 * (m[(0, 1)] + m[(1, 0)]),
        0.5 * (m[(0, 2)] + m[(2, 0)]),
        0.5 * (m[(1, 2)] + m[(2, 1)]),
    ]
}

fn sym3_matrix(m: &Sym3) -> Matrix3<f32> {
    Matrix3::new(m[0], m[3], m[4], m[3], m[1], m[5], m[4], m[5], m[2])
}

impl ModelStream {
    /// A stream for a device whose frame origin sits at `origin_world_mm`.
    pub fn new(params: DeadbandParams, origin_world_mm: Vec3) -> Self {
        Self {
            params,
            origin_world_mm,
            last_sent: None,
            last_sent_s: f64::NEG_INFINITY,
            seq: 0,
            counters: StreamCounters::default(),
            reach_speed_mm_s: 0.0,
            reach_updated_s: f64::NEG_INFINITY,
        }
    }

    /// Counters so far.
    pub fn counters(&self) -> StreamCounters {
        self.counters
    }

    /// The validity radius for a device whose newest pose is `pose`, mm: [`MODEL_RADIUS_MM`] plus the distance
    /// the hand may cover before the next model arrives, at most [`MAX_MODEL_RADIUS_MM`]. Updates the decaying
    /// peak speed. Non-finite speeds or round trips count as zero.
    fn radius_mm(&mut self, now_s: f64, pose: &DevicePose) -> f32 {
        let v = pose.linear_velocity_mm_s;
        let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let speed = if speed.is_finite() { speed } else { 0.0 };
        let elapsed = (now_s - self.reach_updated_s).max(0.0);
        let keep = if elapsed.is_finite() {
            (-elapsed / REACH_SPEED_MEMORY_S).exp() as f32
        } else {
            0.0
        };
        self.reach_speed_mm_s = (self.reach_speed_mm_s * keep).max(speed);
        self.reach_updated_s = now_s;
        let horizon_s = pose.round_trip_us as f32 * 1e-6 + self.params.heartbeat_s as f32;
        let radius = MODEL_RADIUS_MM + self.reach_speed_mm_s * horizon_s;
        if radius.is_finite() {
            radius.clamp(MODEL_RADIUS_MM, MAX_MODEL_RADIUS_MM)
        } else {
            MODEL_RADIUS_MM
        }
    }

    /// The local model of `out` in the device frame, with forces limited to `max_force_n`, valid within
    /// [`MODEL_RADIUS_MM`] of its `x0`.
    pub fn model(&self, now_s: f64, out: &ToolOutput, max_force_n: f32) -> LocalModel {
        self.model_within(now_s, out, max_force_n, MODEL_RADIUS_MM)
    }

    fn model_within(
        &self,
        now_s: f64,
        out: &ToolOutput,
        max_force_n: f32,
        radius_mm: f32,
    ) -> LocalModel {
        let origin = self.origin_world_mm;
        // The drag of cutting is rendered against the device's own motion (`cut_drag_n`), not from f0; a
        // frictional contact's friction from the device's own stick point (`friction_coefficient`).
        let friction = out.friction_coefficient.is_finite()
            && out.friction_coefficient > 0.0
            && out.stick_stiffness_n_per_mm.is_finite()
            && out.stick_stiffness_n_per_mm > 0.0
            && !out.attached;
        let rendered_apart = if friction {
            out.cut_drag_world_n + out.friction_world_n
        } else {
            out.cut_drag_world_n
        };
        let f0 = clamp_to(out.force_world_n - rendered_apart, max_force_n);
        let mut planes = [ContactPlane::default(); MAX_CONTACT_PLANES];
        let count = usize::from(out.plane_count).min(MAX_CONTACT_PLANES);
        for (wire, plane) in planes.iter_mut().zip(&out.planes[..count]) {
            *wire = ContactPlane {
                normal: plane.normal.into(),
                offset_mm: plane.offset_mm - plane.normal.dot(&origin),
                stiffness_n_per_mm: plane.stiffness_n_per_mm,
                damping_n_s_per_mm: plane.damping_n_s_per_mm,
            };
        }
        LocalModel {
            server_time_ns: (now_s.max(0.0) * 1e9) as u64,
            in_contact: out.in_contact,
            // A grasp is linearised about the device position that drove the tool, its K in series with the
            // coupling (`Sim::local_model`); a push about the tool, its K the tissue's.
            x0_mm: (if out.attached {
                out.device_world_mm
            } else {
                out.position_world_mm
            } - origin)
                .into(),
            f0_n: f0.into(),
            // The wire refuses anything but positive semi-definite: send the PSD part, whatever came in.
            stiffness_n_per_mm: sym3(&psd_part(&out.stiffness_n_per_mm)),
            damping_n_s_per_mm: sym3(&psd_part(&out.damping_n_s_per_mm)),
            radius_mm,
            fade_mm: MODEL_FADE_MM,
            planes,
            plane_count: count as u8,
            energy_allowance_mj: out.energy_allowance_mj.max(0.0),
            attached: out.attached,
            cut_drag_n: if out.cut_drag_n.is_finite() {
                out.cut_drag_n.clamp(0.0, max_force_n)
            } else {
                0.0
            },
            friction_coefficient: if friction {
                out.friction_coefficient.min(MAX_FRICTION_COEFFICIENT)
            } else {
                0.0
            },
            stick_stiffness_n_per_mm: if friction {
                out.stick_stiffness_n_per_mm
            } else {
                0.0
            },
            cut_facet_mm: if out.cut_facet_mm.is_finite() && out.cut_drag_n > 0.0 {
                out.cut_facet_mm.max(0.0)
            } else {
                0.0
            },
            puncture: puncture_term(&out.needle_pop, max_force_n),
        }
    }

    /// This tick's command for a device whose newest pose is `pose`, or None when a moderated device does not
    /// need one (within the deadband). `max_force_n` is the smaller of the tool's and the device's limits.
    /// Real-time contract: no allocation, never panics, never a non-finite force.
    pub fn command(
        &mut self,
        now_s: f64,
        out: &ToolOutput,
        pose: &DevicePose,
        max_force_n: f32,
    ) -> Option<ForceCommand> {
        let radius_mm = self.radius_mm(now_s, pose);
        let model = self.model_within(now_s, out, max_force_n, radius_mm);
        let reason = match pose.render_mode {
            RenderMode::Direct => Some(SendReason::Change),
            RenderMode::Moderated => self.send_reason(now_s, &model),
        };
        match reason {
            None => {
                self.counters.suppressed += 1;
                return None;
            }
            Some(SendReason::Heartbeat) => self.counters.heartbeats += 1,
            Some(SendReason::Change) => {}
        }
        // Direct mode streams the tissue's force on the tool (its f0), as a classic virtual coupling
        // renders its spring: extrapolating to the device pose (f0 - K (x_d - x0) - D (v_d - v0)) carried the
        // noise of the fitted K and of the device velocity into a streamed force and kept a held probe from
        // settling (end_to_end::both_pressing...).
        // (With the drag of cutting in it: a direct device feels the drag through this force.)
        let force = clamp_to(out.force_world_n, max_force_n);
        self.last_sent = Some(model);
        self.last_sent_s = now_s;
        self.seq += 1;
        self.counters.sent += 1;
        Some(ForceCommand {
            seq: self.seq,
            echo_pose_seq: pose.seq,
            echo_device_time_ns: pose.device_time_ns,
            force_n: force.into(),
            mode: ForceMode::LocalModel(model),
            in_contact: out.in_contact,
            // Set by the node from the pose's sender; the sim core knows no instances.
            device_instance: 0,
            pose_wait_us: None,
        })
    }

    /// The explicit zero a device gets once when its tool is released; the stream starts afresh after it.
    pub fn release(&mut self, pose: &DevicePose) -> ForceCommand {
        self.last_sent = None;
        self.seq += 1;
        self.counters.sent += 1;
        ForceCommand {
            seq: self.seq,
            echo_pose_seq: pose.seq,
            echo_device_time_ns: pose.device_time_ns,
            force_n: [0.0; 3],
            mode: ForceMode::Direct,
            in_contact: false,
            device_instance: 0,
            pose_wait_us: None,
        }
    }

    /// Whether `model` goes out this tick, and why: a perceptible change first, else the heartbeat.
    fn send_reason(&self, now_s: f64, model: &LocalModel) -> Option<SendReason> {
        if self.differs_perceptibly(model) {
            return Some(SendReason::Change);
        }
        // The tolerance keeps float rounding of tick times from stretching the period by a tick.
        (now_s - self.last_sent_s >= self.params.heartbeat_s - HEARTBEAT_TOLERANCE_S)
            .then_some(SendReason::Heartbeat)
    }

    /// Whether `model` differs from the last one sent by more than the deadband (always, before the first).
    fn differs_perceptibly(&self, model: &LocalModel) -> bool {
        let Some(last) = &self.last_sent else {
            return true;
        };
        let p = &self.params;
        if last.in_contact != model.in_contact
            || last.attached != model.attached
            || (last.cut_drag_n - model.cut_drag_n).abs()
                > p.force_floor_n.max(p.weber_fraction * model.cut_drag_n)
            || last.plane_count != model.plane_count
            || (last.energy_allowance_mj - model.energy_allowance_mj).abs() > p.allowance_mj
            || (last.cut_facet_mm > 0.0) != (model.cut_facet_mm > 0.0)
            || (last.cut_facet_mm - model.cut_facet_mm).abs()
                > p.stiffness_fraction * last.cut_facet_mm
            || last.friction_coefficient != model.friction_coefficient
            || last.puncture.press != model.puncture.press
            || (last.stick_stiffness_n_per_mm - model.stick_stiffness_n_per_mm).abs()
                > p.stiffness_fraction * last.stick_stiffness_n_per_mm.max(0.01)
        {
            return true;
        }
        // What the device renders from the last model at the new x0, against the new f0.
        let k_last = sym3_matrix(&last.stiffness_n_per_mm);
        let predicted =
            Vec3::from(last.f0_n) - k_last * (Vec3::from(model.x0_mm) - Vec3::from(last.x0_mm));
        let f0 = Vec3::from(model.f0_n);
        if (f0 - predicted).norm() > p.force_floor_n.max(p.weber_fraction * f0.norm()) {
            return true;
        }
        let k_new = sym3_matrix(&model.stiffness_n_per_mm);
        if (k_new - k_last).norm() > p.stiffness_fraction * k_last.norm().max(0.01) {
            return true;
        }
        last.active_planes()
            .iter()
            .zip(model.active_planes())
            .any(|(a, b)| {
                (a.offset_mm - b.offset_mm).abs() > p.plane_offset_mm
                    || Vec3::from(a.normal).dot(&Vec3::from(b.normal)) < p.plane_normal_cos
                    || (a.stiffness_n_per_mm - b.stiffness_n_per_mm).abs()
                        > p.stiffness_fraction * a.stiffness_n_per_mm.max(0.01)
            })
    }
}

/// The wire's [`PunctureTerm`] of a needle's pop (world and device axes are parallel), its forces limited to
/// `max_force_n`; inactive when the pop is not (a threshold past the limit, or anything non-finite: a device
/// never pops what it cannot render).
fn puncture_term(pop: &NeedlePop, max_force_n: f32) -> PunctureTerm {
    let axis = pop.tip_axis.try_normalize(1e-6);
    match axis {
        Some(axis)
            if pop.press != 0
                && pop.pop_at_n.is_finite()
                && pop.pop_at_n > 0.0
                && pop.pop_at_n <= max_force_n
                && pop.drag_after_n.is_finite() =>
        {
            PunctureTerm {
                press: pop.press,
                pop_at_n: pop.pop_at_n,
                tip_axis: axis.into(),
                f0_after_n: clamp_to(pop.f0_after_n, max_force_n).into(),
                stiffness_after_n_per_mm: sym3(&psd_part(&pop.stiffness_after_n_per_mm)),
                drag_after_n: pop.drag_after_n.clamp(0.0, max_force_n),
                tip_lever_mm: pop.tip_lever_mm.into(),
                orientation_xyzw: pop.orientation.coords.into(),
            }
        }
        _ => PunctureTerm::default(),
    }
}

/// `force` scaled down to `max_force_n` if it is larger.
fn clamp_to(mut force: Vec3, max_force_n: f32) -> Vec3 {
    let magnitude = force.norm();
    if magnitude > max_force_n {
        force *= max_force_n / magnitude;
    }
    force
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(force_z: f32, x0_z: f32) -> ToolOutput {
        ToolOutput {
            force_world_n: Vec3::new(0.0, 0.0, force_z),
            in_contact: true,
            held_nodes: 10,
            position_world_mm: Vec3::new(0.0, 0.0, x0_z),
            device_world_mm: Vec3::new(0.0, 0.0, x0_z),
            stiffness_n_per_mm: Matrix3::from_diagonal(&Vec3::new(0.0, 0.0, 0.2)),
            ..ToolOutput::default()
        }
    }

    fn moderated() -> DevicePose {
        DevicePose {
            render_mode: RenderMode::Moderated,
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..DevicePose::default()
        }
    }

    #[test]
    fn a_still_moderated_device_gets_only_heartbeats() {
        let mut stream = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        let out = contact(1.0, -3.0);
        let mut sent = 0;
        for tick in 0..1000 {
            if stream
                .command(f64::from(tick) * 0.001, &out, &moderated(), 3.3)
                .is_some()
            {
                sent += 1;
            }
        }
        // One at start, then every 7 ms.
        assert!((142..=144).contains(&sent), "{sent} messages in 1 s");
        assert_eq!(stream.counters().sent, sent);
        // The first is news (no model before it); every other one is a heartbeat.
        assert_eq!(stream.counters().heartbeats, sent - 1);
    }

    #[test]
    fn a_change_the_model_does_not_predict_is_sent_and_one_it_predicts_is_not() {
        let mut stream = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        let pose = moderated();
        assert!(
            stream
                .command(0.0, &contact(1.0, -3.0), &pose, 3.3)
                .is_some()
        );
        // Pressed 0.5 mm deeper with the force the model predicts (1 + 0.2 * 0.5): nothing to send.
        assert!(
            stream
                .command(0.001, &contact(1.1, -3.5), &pose, 3.3)
                .is_none()
        );
        // Same place, the force jumped by 0.2 N (the other surgeon pushed): sent.
        assert!(
            stream
                .command(0.002, &contact(1.3, -3.0), &pose, 3.3)
                .is_some()
        );
        // Contact ends: sent.
        assert!(
            stream
                .command(0.003, &ToolOutput::default(), &pose, 3.3)
                .is_some()
        );
        // Three news, none of them a heartbeat.
        assert_eq!(stream.counters().heartbeats, 0);
        assert_eq!(stream.counters().sent, 3);
    }

    #[test]
    fn a_moving_distant_hand_gets_a_radius_that_covers_its_reach_until_the_next_model() {
        let mut stream = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        let radius = |stream: &mut ModelStream, t: f64, speed: f32, rtt_us: u32| {
            let pose = DevicePose {
                linear_velocity_mm_s: [speed, 0.0, 0.0],
                round_trip_us: rtt_us,
                ..moderated()
            };
            match stream.command(t, &contact(1.0, -3.0), &pose, 3.3) {
                Some(ForceCommand {
                    mode: ForceMode::LocalModel(model),
                    ..
                }) => model.radius_mm,
                other => panic!("{other:?}"),
            }
        };
        // At rest, or near: the base radius.
        assert_eq!(radius(&mut stream, 0.0, 0.0, 100_000), MODEL_RADIUS_MM);
        // 100 mm/s at 100 ms: the hand covers 10 mm + the 7 ms heartbeat's 0.7 mm before the next model.
        let r = radius(&mut stream, 1.0, 100.0, 100_000);
        assert!((r - (MODEL_RADIUS_MM + 10.7)).abs() < 1e-3, "{r}");
        // A stroke's turn-around (speed 0 for an instant) keeps most of it; a long rest lets it go.
        let r = radius(&mut stream, 1.05, 0.0, 100_000);
        assert!(r > MODEL_RADIUS_MM + 0.9 * 10.7, "{r}");
        let r = radius(&mut stream, 5.0, 0.0, 100_000);
        assert!(r < MODEL_RADIUS_MM + 0.01, "{r}");
        // Bounded, and garbage counts as rest.
        assert_eq!(
            radius(&mut stream, 6.0, 1e6, 1_000_000),
            MAX_MODEL_RADIUS_MM
        );
        let mut fresh = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        assert_eq!(radius(&mut fresh, 0.0, f32::NAN, u32::MAX), MODEL_RADIUS_MM);
    }

    #[test]
    fn a_frictional_contact_sends_its_cone_and_leaves_its_friction_out_of_f0() {
        let mut stream = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        let pose = moderated();
        let mut out = contact(1.0, -3.0);
        out.force_world_n = Vec3::new(-0.2, 0.0, 1.0);
        out.friction_world_n = Vec3::new(-0.2, 0.0, 0.0);
        out.friction_coefficient = 0.3;
        out.stick_stiffness_n_per_mm = 1.5;
        let model = |command: Option<ForceCommand>| match command {
            Some(ForceCommand {
                mode: ForceMode::LocalModel(model),
                force_n,
                ..
            }) => (model, force_n),
            other => panic!("{other:?}"),
        };
        let (m, direct) = model(stream.command(0.0, &out, &pose, 3.3));
        assert_eq!(m.f0_n, [0.0, 0.0, 1.0], "f0 is the push alone");
        assert_eq!(
            direct,
            [-0.2, 0.0, 1.0],
            "the direct force keeps the friction"
        );
        assert_eq!(
            (m.friction_coefficient, m.stick_stiffness_n_per_mm),
            (0.3, 1.5)
        );
        m.validate().unwrap();
        // The friction changing within the cone is the device's business: nothing to send.
        out.force_world_n = Vec3::new(0.1, 0.0, 1.0);
        out.friction_world_n = Vec3::new(0.1, 0.0, 0.0);
        assert!(stream.command(0.001, &out, &pose, 3.3).is_none());
        // The cone changing is sent.
        out.friction_coefficient = 0.35;
        assert!(stream.command(0.002, &out, &pose, 3.3).is_some());
        // A grasp, or no stick spring: no friction term, and f0 keeps the friction.
        for (attached, stick) in [(true, 1.5), (false, 0.0)] {
            out.attached = attached;
            out.stick_stiffness_n_per_mm = stick;
            let m = stream.model(0.003, &out, 3.3);
            assert_eq!(m.f0_n, [0.1, 0.0, 1.0]);
            assert_eq!(
                (m.friction_coefficient, m.stick_stiffness_n_per_mm),
                (0.0, 0.0)
            );
        }
    }

    #[test]
    fn an_indefinite_stiffness_is_never_sent() {
        // Regression: a fitted correction along one normal on top of a solve along another made K indefinite,
        // and the device refused every model until its silence rule ramped the force to zero.
        let stream = ModelStream::new(DeadbandParams::default(), Vec3::zeros());
        let mut out = contact(1.0, -3.0);
        let a = Vec3::new(0.0, 0.6, 0.8);
        let b = Vec3::new(0.0, 0.0, 1.0);
        out.stiffness_n_per_mm = a * a.transpose() * 0.7 - b * b.transpose() * 0.5;
        let model = stream.model(0.0, &out, 3.3);
        model.validate().unwrap();
    }

    #[test]
    fn a_direct_device_gets_every_tick_with_the_force_on_its_tool() {
        let mut stream = ModelStream::new(DeadbandParams::default(), Vec3::new(10.0, 0.0, 0.0));
        let mut out = contact(1.0, -3.0);
        // The device pose is 1 mm deeper than the tool (the coupling's lag): direct mode streams the tissue's
        // force on the tool, 1.0 N, not an extrapolation to the device (1.2 N), which carried K's noise.
        out.device_world_mm = Vec3::new(0.0, 0.0, -4.0);
        let pose = DevicePose {
            seq: 7,
            device_time_ns: 99,
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..DevicePose::default()
        };
        for tick in 0..5 {
            let command = stream
                .command(f64::from(tick) * 0.001, &out, &pose, 3.3)
                .unwrap();
            assert!((command.force_n[2] - 1.0).abs() < 1e-5, "{command:?}");
            assert_eq!(
                (command.echo_pose_seq, command.echo_device_time_ns),
                (7, 99)
            );
            let ForceMode::LocalModel(model) = command.mode else {
                panic!("no model")
            };
            // Device frame: the world shifted by the device origin.
            assert_eq!(model.x0_mm, [-10.0, 0.0, -3.0]);
            model.validate().unwrap();
        }
        // The force limit applies to f0 and to the direct force.
        let command = stream
            .command(0.01, &contact(9.0, -3.0), &pose, 2.0)
            .unwrap();
        let ForceMode::LocalModel(model) = command.mode else {
            panic!("no model")
        };
        assert!((model.f0_n[2] - 2.0).abs() < 1e-5);
        assert!(command.force_n[2] <= 2.0 + 1e-5);
    }
}

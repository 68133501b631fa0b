//! A needle let go in free space: a rigid body that falls under gravity and comes to rest on the tissue.
//!
//! Owns: [`NeedleFall`] (a loose needle's velocity and spin, its mass model, and the tick that moves it). A
//! needle held by jaws, or by its holes in tissue, does not fall (`needle_hold.rs`); one let go in free space
//! does, until jaws take it again (the driver's instrument decides: `sim/instruments/needle_driver.rs`).
//!
//! - **The body.** The wire as [`SAMPLES`] equal masses along its arc: the inertia of a thin rod bent on the
//!   arc (a wire 40 times longer than thick), about the masses' centre.
//! - **The tick** is position-based (XPBD rigid bodies, Müller et al. 2020). Gravity predicts the pose. Each
//!   sample meets the tissue's surfaces where its path this tick crosses into one, or where it lies within
//!   the wire's radius above a face under it. Each meeting is a one-sided constraint (the sample's axis the
//!   radius above the face's plane), solved on the body's position and rotation together through its
//!   generalised inverse mass `1/m + (r x n)^T I^-1 (r x n)`, Gauss-Seidel over [`ITERATIONS`] passes.
//!   Coulomb friction then takes back each contact's slide along its face as far as [`FRICTION`] times its
//!   push allows (a contact that slid less sticks; one that slid more slides on, slowed). The velocities are
//!   read from the pose's change.
//! - **Tools push it**: a sample that comes within the wire's radius of a tool part it was clear of at the
//!   last tick is put the radius clear of it, the tool moving as it is driven (it does not feel the needle). A
//!   sample inside a part at the last tick is left alone until clear of it: the jaws that just let the needle
//!   go hold it inside their body. Which parts push is the caller's (open jaws part round the wire: the
//!   driver's instrument leaves them out).
//! - **Not modelled.** The tissue does not feel the needle's weight (a 30 mg needle weighs 0.3 mN, far under
//!   any force a device renders), nor the needle the thread's pull on its tail.
//!
//! Must not: allocate or panic; a non-finite input or result leaves the needle where it was, at rest.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion};

use super::NeedleArc;
use super::thread::{ThreadObject, ThreadTool};
use crate::collision::{crossing_nearest, nearest_face, project_on_face};
use crate::tissue::Vec3;

/// Masses along the arc, its ends included.
pub const SAMPLES: usize = 17;
/// Gauss-Seidel passes over the contacts a tick.
const ITERATIONS: usize = 8;
/// Static friction between the wire and wet tissue (needle-tissue coefficients are 0.12-0.34: issue 32).
const FRICTION: f32 = 0.3;
/// A face within this much past the radius of a sample is met, mm.
const FACE_REACH_MM: f32 = 0.5;
/// The tree's query box is loosened by this much for a sample's path, mm.
const CROSSING_MARGIN_MM: f32 = 0.5;
/// Air and wetness drag, 1/s.
const DRAG_PER_S: f32 = 2.0;
/// Tool parts met (the first this many: 16 tools, each a tip and a shaft).
const MAX_TOOL_PARTS: usize = 32;

/// One sample's meeting with a surface this tick: the sample, the face's plane (a point on it and its unit
/// outward normal), and the push along the normal so far (mass-weighted, for friction).
#[derive(Debug, Clone, Copy)]
struct Contact {
    sample: usize,
    on_plane_mm: Vec3,
    normal: Vec3,
    push: f32,
}

/// A loose needle's motion (module doc).
#[derive(Debug, Clone)]
pub struct NeedleFall {
    /// The samples in the needle's frame, relative to their centre, mm.
    samples_mm: [Vec3; SAMPLES],
    /// Their centre in the needle's frame, mm.
    centre_mm: Vec3,
    /// The body's inverse inertia in the needle's frame, per unit sample mass (1/mm^2; the whole mass is
    /// `SAMPLES`).
    inverse_inertia: Matrix3<f32>,
    /// The wire's radius, mm.
    radius_mm: f32,
    /// The centre's velocity, world, mm/s.
    velocity_mm_s: Vec3,
    /// The spin, world, rad/s.
    spin_rad_s: Vec3,
    /// This tick's meetings: per sample its tissue's (first `SAMPLES`), then its tool's.
    contacts: [Option<Contact>; 2 * SAMPLES],
    /// Per sample, the tool parts it lay within half the radius of at the end of the last tick (bit `k`: part
    /// `k`).
    in_tools: [u32; SAMPLES],
    /// It fell at the last tick (else `in_tools` is taken where it lies before it moves).
    falling: bool,
}

impl NeedleFall {
    /// The body of a needle on `arc`, of wire `diameter_mm` thick, at rest.
    pub fn new(arc: &NeedleArc, diameter_mm: f32) -> Self {
        let points: [Vec3; SAMPLES] = std::array::from_fn(|k| {
            arc.at(arc.sweep_rad() * k as f32 / (SAMPLES - 1) as f32)
                .point_mm
        });
        let centre_mm = points.iter().sum::<Vec3>() / SAMPLES as f32;
        let samples_mm = points.map(|p| p - centre_mm);
        // Point masses, and each a short rod's own inertia across it (keeps a straight wire's from being
        // singular about its axis).
        let radius_mm = 0.5 * diameter_mm.max(0.0);
        let spacing_mm = arc.radius_mm() * arc.sweep_rad() / (SAMPLES - 1) as f32;
        let own = (spacing_mm * spacing_mm / 12.0 + radius_mm * radius_mm / 2.0).max(1e-6);
        let inertia = samples_mm.iter().fold(Matrix3::zeros(), |sum, r| {
            sum + Matrix3::identity() * (r.norm_squared() + own) - r * r.transpose()
        });
        Self {
            samples_mm,
            centre_mm,
            inverse_inertia: inertia.try_inverse().unwrap_or_else(Matrix3::zeros),
            radius_mm,
            velocity_mm_s: Vec3::zeros(),
            spin_rad_s: Vec3::zeros(),
            contacts: [None; 2 * SAMPLES],
            in_tools: [0; SAMPLES],
            falling: false,
        }
    }

    /// At rest (jaws took it, or it was placed).
    pub fn stop(&mut self) {
        self.velocity_mm_s = Vec3::zeros();
        self.spin_rad_s = Vec3::zeros();
        self.falling = false;
    }

    /// The centre's speed, mm/s.
    pub fn speed_mm_s(&self) -> f32 {
        self.velocity_mm_s.norm()
    }

    /// One tick of `dt_s` from `world_from_needle` under `gravity_mm_per_s2`, against the surfaces of
    /// `objects` objects (`object(o)`) and the tool parts `tool(0..tools)` at their poses this tick: the
    /// needle's pose after it. A bad input or a non-finite result returns the pose given, and stops the needle.
    /// No allocation.
    #[allow(clippy::too_many_arguments)] // the pose and tick, and what the needle meets: objects and tools
    pub fn step<'a, 'b>(
        &mut self,
        world_from_needle: &Isometry3<f32>,
        dt_s: f32,
        gravity_mm_per_s2: &Vec3,
        objects: usize,
        object: impl Fn(usize) -> Option<ThreadObject<'a>>,
        tools: usize,
        tool: impl Fn(usize) -> Option<ThreadTool<'b>>,
    ) -> Isometry3<f32> {
        let finite_in = dt_s > 0.0
            && dt_s.is_finite()
            && gravity_mm_per_s2.iter().all(|c| c.is_finite())
            && finite(world_from_needle);
        if !finite_in {
            self.stop();
            return *world_from_needle;
        }
        let rotation = world_from_needle.rotation;
        let centre = world_from_needle * Point3::from(self.centre_mm);
        let tools = tools.min(MAX_TOOL_PARTS);
        if !self.falling {
            // Just let go: inside the jaws that held it, and to be left there until clear of them.
            self.mark_tools(&centre.coords, &rotation, tools, &tool);
            self.falling = true;
        }
        let drag = 1.0 / (1.0 + DRAG_PER_S * dt_s);
        self.velocity_mm_s = (self.velocity_mm_s + gravity_mm_per_s2 * dt_s) * drag;
        self.spin_rad_s *= drag;
        let mut x = centre.coords + self.velocity_mm_s * dt_s;
        let mut q = UnitQuaternion::from_scaled_axis(self.spin_rad_s * dt_s) * rotation;
        let before: [Vec3; SAMPLES] =
            std::array::from_fn(|k| centre.coords + rotation * self.samples_mm[k]);
        let down = gravity_mm_per_s2
            .try_normalize(1e-6)
            .unwrap_or(Vec3::new(0.0, 0.0, -1.0));
        self.find_contacts(&before, &x, &q, &down, objects, &object);
        self.meet_tools(&x, &q, tools, &tool);
        for _ in 0..ITERATIONS {
            for k in 0..2 * SAMPLES {
                let Some(mut contact) = self.contacts[k] else {
                    continue;
                };
                let r = q * self.samples_mm[contact.sample];
                let depth = self.radius_mm - contact.normal.dot(&(x + r - contact.on_plane_mm));
                if depth <= 0.0 {
                    continue;
                }
                let push = self.correct(&mut x, &mut q, &r, &(contact.normal * depth));
                contact.push += push;
                self.contacts[k] = Some(contact);
            }
        }
        // Coulomb friction: a contact's slide along its face is taken back as far as FRICTION times its push
        // allows (all of it: it sticks; part: it slides, slowed).
        for k in 0..2 * SAMPLES {
            let Some(contact) = self.contacts[k] else {
                continue;
            };
            let r = q * self.samples_mm[contact.sample];
            let slid = x + r - before[contact.sample];
            let along = slid - contact.normal * contact.normal.dot(&slid);
            let w = self.inverse_mass_along(&q, &r, &along);
            let slide_mm = along.norm();
            if !(w > 0.0 && slide_mm > 0.0) {
                continue;
            }
            let share = (FRICTION * contact.push * w / slide_mm).min(1.0);
            self.correct_by(&mut x, &mut q, &r, &(-along * share), w);
        }
        self.mark_tools(&x, &q, tools, &tool);
        // Renormalised: a tick composes a few hundred small turns, and a rotation that drifts off unit length
        // scales the needle.
        let q = UnitQuaternion::new_normalize(q.into_inner());
        let velocity = (x - centre.coords) / dt_s;
        let spin = (q * rotation.inverse()).scaled_axis() / dt_s;
        let pose = Isometry3::from_parts(Translation3::from(x - q * self.centre_mm), q);
        if !(finite(&pose) && velocity.iter().chain(spin.iter()).all(|c| c.is_finite())) {
            self.stop();
            return *world_from_needle;
        }
        self.velocity_mm_s = velocity;
        self.spin_rad_s = spin;
        pose
    }

    /// Each sample's meeting with a surface this tick, its path from `before` to where the predicted pose
    /// (centre `x`, rotation `q`) puts it: the first surface it crosses into, else the nearest face under it
    /// within reach (facing against `down`).
    fn find_contacts<'a>(
        &mut self,
        before: &[Vec3; SAMPLES],
        x: &Vec3,
        q: &UnitQuaternion<f32>,
        down: &Vec3,
        objects: usize,
        object: &impl Fn(usize) -> Option<ThreadObject<'a>>,
    ) {
        self.contacts = [None; 2 * SAMPLES];
        for (k, from) in before.iter().enumerate() {
            let to = x + q * self.samples_mm[k];
            let mut best: Option<(f32, Contact)> = None;
            for o in 0..objects {
                let Some((collider, model, state)) = object(o) else {
                    continue;
                };
                let (triangles, positions) = (model.triangles(), &state.positions_mm);
                let crossing = crossing_nearest(
                    collider,
                    triangles,
                    positions,
                    from,
                    &to,
                    CROSSING_MARGIN_MM,
                    0.0,
                    Some(true),
                )
                .and_then(|hit| {
                    let corners = *triangles.get(hit.triangle as usize)?;
                    let (_, _, normal) = project_on_face(positions, corners, &hit.point_mm)?;
                    Some((hit.along - 1.0, hit.point_mm, normal))
                });
                let under = || {
                    let face = nearest_face(
                        collider,
                        triangles,
                        positions,
                        &to,
                        down,
                        self.radius_mm + FACE_REACH_MM,
                    )?;
                    let (_, signed, normal) = project_on_face(positions, face.corners, &to)?;
                    (signed < self.radius_mm + FACE_REACH_MM).then_some((
                        signed,
                        to - normal * signed,
                        normal,
                    ))
                };
                // A crossing (ranked before any face under, earliest first) wins over a face under it.
                if let Some((rank, on_plane_mm, normal)) = crossing.or_else(under)
                    && best.is_none_or(|(b, _)| rank < b)
                {
                    best = Some((
                        rank,
                        Contact {
                            sample: k,
                            on_plane_mm,
                            normal,
                            push: 0.0,
                        },
                    ));
                }
            }
            self.contacts[k] = best.map(|(_, c)| c);
        }
    }

    /// Each sample within the radius of a tool part it was clear of at the last tick meets that part: a
    /// contact on the part's surface, its normal outward (beside its tissue's: squeezed between the two, the
    /// passes share the overlap).
    fn meet_tools<'b>(
        &mut self,
        x: &Vec3,
        q: &UnitQuaternion<f32>,
        tools: usize,
        tool: &impl Fn(usize) -> Option<ThreadTool<'b>>,
    ) {
        for k in 0..SAMPLES {
            let at = x + q * self.samples_mm[k];
            for part in 0..tools {
                let Some((collider, position_mm, rotation)) = tool(part) else {
                    continue;
                };
                if self.in_tools[k] & (1 << part) != 0 {
                    continue;
                }
                let Some(to) = collider.keep_clear(&position_mm, &rotation, &at, self.radius_mm)
                else {
                    continue;
                };
                let Some(normal) = (to - at).try_normalize(1e-9) else {
                    continue;
                };
                self.contacts[SAMPLES + k] = Some(Contact {
                    sample: k,
                    on_plane_mm: to - normal * self.radius_mm,
                    normal,
                    push: 0.0,
                });
            }
        }
    }

    /// Mark the tool parts each sample lies within half the radius of now (centre `x`, rotation `q`): inside
    /// them, to be left alone until clear.
    fn mark_tools<'b>(
        &mut self,
        x: &Vec3,
        q: &UnitQuaternion<f32>,
        tools: usize,
        tool: &impl Fn(usize) -> Option<ThreadTool<'b>>,
    ) {
        for k in 0..SAMPLES {
            let at = x + q * self.samples_mm[k];
            self.in_tools[k] = (0..tools)
                .filter(|&part| {
                    tool(part).is_some_and(|(collider, position_mm, rotation)| {
                        collider.distance_mm(&position_mm, &rotation, &at) < 0.5 * self.radius_mm
                    })
                })
                .fold(0, |bits, part| bits | (1 << part));
        }
    }

    /// The inverse mass the body shows at arm `r` (world) along `direction` (any length; 0 for none), per
    /// unit sample mass.
    fn inverse_mass_along(&self, q: &UnitQuaternion<f32>, r: &Vec3, direction: &Vec3) -> f32 {
        let Some(n) = direction.try_normalize(1e-9) else {
            return 0.0;
        };
        let rn = q.inverse() * r.cross(&n);
        1.0 / SAMPLES as f32 + rn.dot(&(self.inverse_inertia * rn))
    }

    /// Move the body so its point at arm `r` (world) moves by `by_mm` (to first order), position and
    /// rotation shared by their inverse masses. Returns the push, `|by| / w` (mass-weighted).
    fn correct(&self, x: &mut Vec3, q: &mut UnitQuaternion<f32>, r: &Vec3, by_mm: &Vec3) -> f32 {
        let w = self.inverse_mass_along(q, r, by_mm);
        self.correct_by(x, q, r, by_mm, w)
    }

    /// [`Self::correct`] with the inverse mass `w` along `by_mm` already known.
    fn correct_by(
        &self,
        x: &mut Vec3,
        q: &mut UnitQuaternion<f32>,
        r: &Vec3,
        by_mm: &Vec3,
        w: f32,
    ) -> f32 {
        if !(w > 0.0 && w.is_finite()) {
            return 0.0;
        }
        let impulse = by_mm / w;
        *x += impulse / SAMPLES as f32;
        let turn = *q * (self.inverse_inertia * (q.inverse() * r.cross(&impulse)));
        *q = UnitQuaternion::from_scaled_axis(turn) * *q;
        impulse.norm()
    }
}

fn finite(pose: &Isometry3<f32>) -> bool {
    pose.translation.vector.iter().all(|c| c.is_finite())
        && pose.rotation.coords.iter().all(|c| c.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_objects(_: usize) -> Option<ThreadObject<'static>> {
        None
    }

    fn no_tools(_: usize) -> Option<ThreadTool<'static>> {
        None
    }

    /// In free space the needle falls as a body under gravity and its drag: after 200 ticks of 1 ms its centre
    /// is where `v' = g - c v` takes it (to 0.1%), it has not turned, and its shape is the same.
    #[test]
    fn a_needle_in_free_space_falls_under_gravity_without_turning() {
        let arc = NeedleArc::new(10.7, 116.0).unwrap();
        let mut fall = NeedleFall::new(&arc, 0.5);
        let start = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.5),
        );
        let g = Vec3::new(0.0, 0.0, -9810.0);
        let (mut pose, mut v, mut z) = (start, 0.0f64, 0.0f64);
        let (dt, c) = (0.001f64, f64::from(DRAG_PER_S));
        for _ in 0..200 {
            pose = fall.step(&pose, 0.001, &g, 0, no_objects, 0, no_tools);
            v = (v - 9810.0 * dt) / (1.0 + c * dt);
            z += v * dt;
        }
        let dropped = f64::from(pose.translation.vector.z - start.translation.vector.z);
        assert!(
            (dropped - z).abs() < 1e-3 * z.abs(),
            "fell {dropped} mm, expected {z}"
        );
        assert!(pose.rotation.angle_to(&start.rotation) < 1e-4);
        assert!((fall.speed_mm_s() as f64 - v.abs()).abs() < 1e-3 * v.abs());
    }

    /// A bad tick (a non-finite pose, gravity or step) leaves the needle where it was, at rest.
    #[test]
    fn a_bad_tick_leaves_the_needle_where_it_was_at_rest() {
        let arc = NeedleArc::new(10.7, 116.0).unwrap();
        let mut fall = NeedleFall::new(&arc, 0.5);
        let pose = Isometry3::translation(0.0, 0.0, 10.0);
        let g = Vec3::new(0.0, 0.0, -9810.0);
        let moving = fall.step(&pose, 0.001, &g, 0, no_objects, 0, no_tools);
        assert!(fall.speed_mm_s() > 0.0);
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        assert_eq!(
            fall.step(&moving, 0.001, &nan, 0, no_objects, 0, no_tools),
            moving
        );
        assert_eq!(fall.speed_mm_s(), 0.0);
        assert_eq!(
            fall.step(&moving, f32::NAN, &g, 0, no_objects, 0, no_tools),
            moving
        );
        let bad = Isometry3::translation(f32::INFINITY, 0.0, 0.0);
        assert_eq!(fall.step(&bad, 0.001, &g, 0, no_objects, 0, no_tools), bad);
        assert_eq!(fall.speed_mm_s(), 0.0);
    }
}

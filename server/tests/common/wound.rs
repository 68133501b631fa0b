//! The wound of worlds/suture.toml driven on virtual time, for the stitch's tests and its bench: a
//! needle driver (tool 0) holding a half-circle needle at its tail in small jaws (so it follows the needle
//! through), turned along the needle's own curve through both edges ([`Wound::pass`]); a grasper (tool 1)
//! that takes the thread ([`Wound::take_thread`]); both ends drawn crossed over the wound by hands that stop
//! drawing at a set pull ([`CrossedDraw`]).
#![allow(dead_code)] // each test or bench uses a part

use nalgebra::{Point3, UnitQuaternion, Vector3};
use sinew_server::interaction::JawInput;
use sinew_server::interaction::suture::SutureThread;
use sinew_server::sim::{Sim, StepReport, ToolCommand, ToolOutput};
use sinew_server::training::{MetricsConfig, SessionEvent, SessionObserver, TickView, Transition};
use sinew_server::world::{InstrumentSpec, World, load_world};

use super::tool_pose::pose_command;

pub const DT_S: f32 = 0.001;
/// The needle's circle: its centre this high above the skin, mm (the tip meets the skin 16 degrees off its
/// normal, inside the 37-degree puncture cone even as the skin tents; the face holes lie 7.4 mm deep).
pub const CENTRE_HEIGHT_MM: f32 = 3.0;
/// The wound's faces, mm.
pub const FACE_X_MM: f32 = 2.5;

/// What [`Wound::pass`] did: the gap before it, the punctures, and the driver's pose at its end.
pub struct Pass {
    pub gap_before_mm: f32,
    pub punctures: u32,
    pub rotation: UnitQuaternion<f32>,
    pub origin_mm: Vector3<f32>,
}

/// The wound world with the needle driver (tool 0) holding a half-circle needle at its tail in small jaws
/// (so it follows the needle through), and the grasper (tool 1).
pub struct Wound {
    pub sim: Sim,
    pub origins_mm: [Vector3<f32>; 2],
    /// The needle's centre and tip in the tool frame, and its tip's direction.
    pub centre_tool: Vector3<f32>,
    pub tip_tool: Vector3<f32>,
    pub tip_dir_tool: Vector3<f32>,
    /// The driver's rotation at turn 0, and where the needle's centre is held.
    pub base: UnitQuaternion<f32>,
    pub centre: Vector3<f32>,
    /// The grasper's command.
    pub grasper: ToolCommand,
    /// The driver's buttons (its first, held, opens its ratchet and lets the needle go).
    pub driver_buttons: u32,
    /// The training layer watching every tick (None: unwatched, as a bench times it).
    pub observer: Option<SessionObserver>,
    /// What it saw: each tool's state changes, and every event.
    pub transitions: Vec<(u8, Transition)>,
    pub events: Vec<SessionEvent>,
}

impl Wound {
    pub fn new() -> Self {
        Self::new_with(|_| {})
    }

    /// The wound with its world edited first by `edit`.
    pub fn new_with(edit: impl FnOnce(&mut World)) -> Self {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture.toml");
        let mut world = load_world(&path).unwrap();
        edit(&mut world);
        // (The world's needle: a half circle held at its tail in small jaws, which follow it through.)
        let InstrumentSpec::NeedleDriver(spec) = world.tools[0].instrument else {
            panic!("tool 0 of the wound world is not a needle driver");
        };
        let tool_from_needle = spec.tool_from_needle();
        Self {
            origins_mm: [0, 1].map(|t| Vector3::from(world.tools[t].device_origin_in_world_mm)),
            sim: Sim::new(&world).unwrap(),
            centre_tool: (tool_from_needle * Point3::origin()).coords,
            tip_tool: (tool_from_needle * Point3::from(spec.arc.tip().point_mm)).coords,
            tip_dir_tool: tool_from_needle * spec.arc.tip().tangent,
            base: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2),
            centre: Vector3::new(0.0, 0.0, CENTRE_HEIGHT_MM),
            grasper: ToolCommand::default(),
            driver_buttons: 0,
            observer: Some(SessionObserver::new(2, MetricsConfig::new(f64::from(DT_S)))),
            // Room for a whole stitch's: recording them allocates nothing in a tick.
            transitions: Vec::with_capacity(1 << 12),
            events: Vec::with_capacity(1 << 14),
        }
    }

    /// The driver's pose turned `turn_rad` about the world's y through the needle's centre.
    pub fn pose_at(&self, turn_rad: f32) -> (UnitQuaternion<f32>, Vector3<f32>) {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), turn_rad) * self.base;
        (rotation, self.centre - rotation * self.centre_tool)
    }

    pub fn tip_at(&self, turn_rad: f32) -> Vector3<f32> {
        let (rotation, origin) = self.pose_at(turn_rad);
        origin + rotation * self.tip_tool
    }

    /// The pass: the grasper parked aside, the driver 8 degrees before the skin for 1.5 s, then on along the
    /// needle's curve at 40 degrees a second until the tail has left all four holes, and 0.5 s more.
    pub fn pass(&mut self) -> Pass {
        self.aim_grasper(&Vector3::new(30.0, 0.0, 30.0), false);
        let (start, sign) = self.start();
        let (rotation, origin) = self.pose_at(start);
        for _ in 0..1500 {
            self.step_at(&rotation, &origin);
        }
        let gap_before_mm = self.gap_mm();
        let mut turn = 0.0f32;
        let mut after = None;
        let mut punctures = 0;
        while after.is_none_or(|ticks| ticks < 500) {
            turn += DT_S * 40f32.to_radians();
            let (rotation, origin) = self.pose_at(start + sign * turn);
            let (_, report) = self.step_at(&rotation, &origin);
            punctures += report.punctures;
            if self.thread().holes().len() == 4 {
                after = Some(after.map_or(0, |t| t + 1));
            }
            // (The tail leaves the fourth hole about 340 degrees on: a turn and a quarter is the bound.)
            assert!(
                turn < 2.5 * std::f32::consts::PI,
                "the tail never left four holes ({} taken, {punctures} punctures)",
                self.thread().holes().len()
            );
        }
        let (rotation, origin_mm) = self.pose_at(start + sign * turn);
        Pass {
            gap_before_mm,
            punctures,
            rotation,
            origin_mm,
        }
    }

    /// The turn 8 degrees before the tip meets the skin going down, and the way to turn to go on.
    pub fn start(&self) -> (f32, f32) {
        let entry = (0..7200)
            .map(|k| -180f32.to_radians() + k as f32 * 0.05f32.to_radians())
            .find(|&turn| {
                let (rotation, _) = self.pose_at(turn);
                self.tip_at(turn).z.abs() < 0.05 && (rotation * self.tip_dir_tool).z < 0.0
            })
            .expect("the tip never reaches the skin going down");
        let (rotation, _) = self.pose_at(entry);
        let ahead = self.tip_at(entry + 0.01) - self.tip_at(entry);
        let sign = ahead.dot(&(rotation * self.tip_dir_tool)).signum();
        (entry - sign * 8f32.to_radians(), sign)
    }

    /// One tick: the driver at `rotation`, `origin_mm`; the grasper at its command. Returns the outputs and the
    /// report, after checking the guard held and every force is finite.
    pub fn step_at(
        &mut self,
        rotation: &UnitQuaternion<f32>,
        origin_mm: &Vector3<f32>,
    ) -> ([ToolOutput; 2], StepReport) {
        let mut driver = pose_command(origin_mm, &self.origins_mm[0], rotation);
        driver.jaws.buttons = self.driver_buttons;
        let command = [driver, self.grasper];
        let mut out = [ToolOutput::default(); 2];
        let report = self.sim.step(DT_S, &command, &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        if let Some(observer) = &mut self.observer {
            let view = TickView {
                tick: self.sim.steps() - 1,
                active: &[true, true],
                outputs: &out,
                step: &report,
            };
            let (events, transitions) = (&mut self.events, &mut self.transitions);
            observer.observe(
                &view,
                |e| {
                    if events.len() < events.capacity() {
                        events.push(*e);
                    }
                },
                |tool, t| {
                    if transitions.len() < transitions.capacity() {
                        transitions.push((tool, *t));
                    }
                },
            );
        }
        for o in &out {
            assert!(o.force_world_n.iter().all(|c| c.is_finite()));
        }
        (out, report)
    }

    /// The grasper at `origin_mm`, its capsule along the world's y, jaws closed or open.
    pub fn aim_grasper(&mut self, origin_mm: &Vector3<f32>, closed: bool) {
        self.pose_grasper(origin_mm, &UnitQuaternion::identity(), closed);
    }

    /// The grasper at `origin_mm`, turned by `turn` from its capsule along the world's y, jaws closed or open.
    pub fn pose_grasper(
        &mut self,
        origin_mm: &Vector3<f32>,
        turn: &UnitQuaternion<f32>,
        closed: bool,
    ) {
        let along_y =
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f32::consts::FRAC_PI_2);
        self.grasper = pose_command(origin_mm, &self.origins_mm[1], &(turn * along_y));
        self.grasper.jaws = JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        };
    }

    pub fn thread(&self) -> &SutureThread {
        self.sim.tools[0].thread().unwrap()
    }

    /// The wound's gap: the least x of the right edge's face nodes minus the most x of the left edge's.
    pub fn gap_mm(&self) -> f32 {
        sinew_server::training::wound_gap_mm(&self.sim.objects[0], &self.sim.objects[1]).unwrap()
    }

    /// Tetrahedra turned inside out, over both edges.
    pub fn inverted(&self) -> usize {
        let mut n = 0;
        for object in &self.sim.objects {
            let x = &object.state.positions_mm;
            for t in &object.model.tets().tets {
                let [a, b, c, d] = t.map(|i| x[i as usize]);
                n += usize::from((b - a).dot(&(c - a).cross(&(d - a))) <= 0.0);
            }
        }
        n
    }
}

impl Wound {
    /// After the pass (the driver held where it ended), the grasper takes the thread `past_mm` along it past
    /// the entry hole, coming down on it from 20 mm above to 0.3 mm beside it and closing. Returns where the
    /// grasper is aimed.
    pub fn take_thread(&mut self, pass: &Pass, past_mm: f32) -> Vector3<f32> {
        let (rotation, driver_at) = (pass.rotation, pass.origin_mm);
        let thread = self.thread();
        let entry_u = thread.holes()[0].u_mm;
        let node = thread
            .chain()
            .node_u_mm()
            .iter()
            .position(|&u| u >= entry_u + past_mm)
            .expect("the thread is shorter than that");
        let beside = Vector3::new(1.5 + 0.3, 0.0, 0.0);
        let mut aim = self.sim.tools[1].position_mm;
        for lift in [20.0, 0.0] {
            for _ in 0..20_000 {
                let waypoint =
                    self.thread().nodes_mm()[node] + beside + Vector3::new(0.0, 0.0, lift);
                let to = waypoint - aim;
                aim += to * (0.02 / to.norm().max(0.02));
                self.aim_grasper(&aim, false);
                self.step_at(&rotation, &driver_at);
                if (self.sim.tools[1].position_mm - waypoint).norm() < 0.02 {
                    break;
                }
            }
        }
        for _ in 0..200 {
            self.aim_grasper(&aim, true);
            self.step_at(&rotation, &driver_at);
        }
        aim
    }
}

/// Both ends of a stitch drawn crossed, as a throw is laid: each end over the wound to the other side (20 mm
/// out, 15 mm up, 3 mm apart in y) over 6 s of drawing, each hand drawing on only while it feels the thread
/// pull under `most_n` (a surgeon does not yank a stitch shut).
pub struct CrossedDraw {
    most_n: f32,
    /// Where each hand (the driver, the grasper) starts and ends.
    from: [Vector3<f32>; 2],
    to: [Vector3<f32>; 2],
    rotation: UnitQuaternion<f32>,
    /// How much of the way each hand has drawn, 0 to 1.
    pub drawn: [f32; 2],
    /// The thread's pull each hand felt last tick, N: on the needle's tail (the driver) and in the jaws.
    pub felt: [f32; 2],
}

/// Ticks a hand takes to draw the whole way.
pub const DRAW_TICKS: f32 = 6000.0;

impl CrossedDraw {
    /// The wound as the stitch's tests start it: the pass, the grasper's take of the thread 15 mm past the
    /// entry hole (checked), and the draw at `most_n` ready to go.
    pub fn after_the_pass(most_n: f32) -> (Wound, Pass, Self) {
        Self::after_the_pass_in(Wound::new(), most_n)
    }

    /// [`Self::after_the_pass`] in `wound` (as made).
    pub fn after_the_pass_in(mut wound: Wound, most_n: f32) -> (Wound, Pass, Self) {
        let pass = wound.pass();
        let grasper_from = wound.take_thread(&pass, 15.0);
        assert!(
            wound.thread().grip_of(1).is_some(),
            "the jaws did not take the thread"
        );
        let draw = Self::new(&wound, &pass, grasper_from, most_n);
        (wound, pass, draw)
    }

    /// The draw from where the pass left the driver and where the grasper took the thread.
    pub fn new(wound: &Wound, pass: &Pass, grasper_from: Vector3<f32>, most_n: f32) -> Self {
        let side = wound.thread().holes()[3].place_mm().x.signum();
        Self {
            most_n,
            from: [pass.origin_mm, grasper_from],
            to: [
                Vector3::new(-side * 20.0, -3.0, 15.0),
                Vector3::new(side * 20.0, 3.0, 15.0),
            ],
            rotation: pass.rotation,
            drawn: [0.0; 2],
            felt: [0.0; 2],
        }
    }

    /// One tick of the draw.
    pub fn step(&mut self, wound: &mut Wound) -> ([ToolOutput; 2], StepReport) {
        for (d, felt) in self.drawn.iter_mut().zip(self.felt) {
            if felt < self.most_n {
                *d = (*d + 1.0 / DRAW_TICKS).min(1.0);
            }
        }
        let at =
            |hand: usize| self.from[hand] + (self.to[hand] - self.from[hand]) * self.drawn[hand];
        wound.aim_grasper(&at(1), true);
        let result = wound.step_at(&self.rotation, &at(0));
        let thread = wound.thread();
        self.felt = [
            thread.pull_on_tail_n().norm(),
            thread.grip_of(1).map_or(0.0, |g| g.pull_n().norm()),
        ];
        result
    }
}

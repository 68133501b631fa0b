//! Who holds the needle: its driver's jaws, another tool's jaws, or nothing (it lies where it was let go, held
//! in the tissue by its holes).
//!
//! Owns: [`NeedleHold`] (the holder, the needle's world pose this tick, and the hand-offs so far). The needle
//! driver that carries the needle (`sim/instruments/needle_driver.rs`) places it each tick from its holder's
//! pose; a grasper's closing jaws take a loose needle ([`NeedleHold::take`]) and its opening jaws let it go
//! ([`NeedleHold::let_go`]), as a surgeon hands a needle from driver to grasper on the far side of a bite.
//!
//! A needle is held at the pose it had when the jaws closed on it (the jaws clamp it where it lies, and it
//! stays fixed in them while they stay closed). A loose needle in tissue is held by its holes, rigid, and the
//! tissue settles around it; out of tissue it falls and comes to rest on the tissue as a rigid body
//! (`needle_fall.rs`, moved by the needle's instrument: [`NeedleHold::lie_at`]).
//!
//! Pure and allocation-free.

use nalgebra::{Isometry3, Point3};

use super::NeedleArc;
use crate::tissue::Vec3;

/// The needle's holder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NeedleHolder {
    /// The jaws of the driver that carries it, at `tool_from_needle` (the tool frame is the driver's).
    Driver {
        /// The needle's pose in the driver's tool frame.
        tool_from_needle: Isometry3<f32>,
    },
    /// Another tool's jaws (a grasper's), at `tool_from_needle` in that tool's frame.
    Tool {
        /// The tool holding it.
        tool: u16,
        /// The needle's pose in that tool's frame.
        tool_from_needle: Isometry3<f32>,
    },
    /// No jaws: the needle lies where it was let go.
    Loose,
}

/// Who holds the needle and where it is (module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleHold {
    holder: NeedleHolder,
    /// The needle's pose this tick, world (the last placed).
    world_from_needle: Isometry3<f32>,
    /// Times the needle was taken by jaws after being let go.
    regrasps: u32,
    /// The needle was taken (by any jaws) while it ran through tissue, and is still held by them.
    taken_in_tissue: bool,
}

/// The arc is searched for the point nearest the jaws at this many places.
const ARC_SAMPLES: usize = 48;

impl NeedleHold {
    /// A needle loaded in its driver's jaws at `tool_from_needle`, the driver at `world_from_tool`.
    pub fn in_driver(tool_from_needle: Isometry3<f32>, world_from_tool: &Isometry3<f32>) -> Self {
        Self {
            holder: NeedleHolder::Driver { tool_from_needle },
            world_from_needle: world_from_tool * tool_from_needle,
            regrasps: 0,
            taken_in_tissue: false,
        }
    }

    /// The holder.
    pub fn holder(&self) -> &NeedleHolder {
        &self.holder
    }

    /// The needle's pose this tick, world.
    pub fn world_from_needle(&self) -> &Isometry3<f32> {
        &self.world_from_needle
    }

    /// Its driver's jaws hold it.
    pub fn in_drivers_jaws(&self) -> bool {
        matches!(self.holder, NeedleHolder::Driver { .. })
    }

    /// Tool `tool`'s jaws hold it (another tool than its driver).
    pub fn held_by(&self, tool: u16) -> bool {
        matches!(self.holder, NeedleHolder::Tool { tool: t, .. } if t == tool)
    }

    /// Times jaws took it after it was let go.
    pub fn regrasps(&self) -> u32 {
        self.regrasps
    }

    /// The jaws that hold it took it while it ran through tissue (a regrasp on the far side of a bite).
    pub fn taken_in_tissue(&self) -> bool {
        self.taken_in_tissue && !matches!(self.holder, NeedleHolder::Loose)
    }

    /// Place the needle for this tick: `driver` is its driver's pose, `tool(k)` tool `k`'s pose if it is
    /// active. A holder that is gone (its tool left) lets go: the needle stays where it was. A non-finite pose
    /// moves nothing. Returns whether the needle was let go.
    pub fn place(
        &mut self,
        driver: &Isometry3<f32>,
        tool: impl Fn(u16) -> Option<Isometry3<f32>>,
    ) -> bool {
        let pose = match self.holder {
            NeedleHolder::Driver { tool_from_needle } => Some(driver * tool_from_needle),
            NeedleHolder::Tool {
                tool: k,
                tool_from_needle,
            } => match tool(k) {
                Some(world_from_tool) => Some(world_from_tool * tool_from_needle),
                None => {
                    self.holder = NeedleHolder::Loose;
                    return true;
                }
            },
            NeedleHolder::Loose => None,
        };
        if let Some(pose) = pose.filter(finite) {
            self.world_from_needle = pose;
        }
        false
    }

    /// A loose needle lies at `world_from_needle` now (it fell: `needle_fall.rs`). Held, or a non-finite pose:
    /// nothing changes.
    pub fn lie_at(&mut self, world_from_needle: Isometry3<f32>) {
        if self.holder == NeedleHolder::Loose && finite(&world_from_needle) {
            self.world_from_needle = world_from_needle;
        }
    }

    /// The jaws of tool `tool` (None: its driver's) opened: if they hold the needle it is let go where it is.
    /// Returns whether they held it.
    pub fn let_go(&mut self, tool: Option<u16>) -> bool {
        let theirs = match (self.holder, tool) {
            (NeedleHolder::Driver { .. }, None) => true,
            (NeedleHolder::Tool { tool: t, .. }, Some(k)) => t == k,
            _ => false,
        };
        if theirs {
            self.holder = NeedleHolder::Loose;
            self.taken_in_tissue = false;
        }
        theirs
    }

    /// Closing jaws at `world_from_tool` (`tool`: None for its driver's) take the needle if a point of its arc
    /// (`arc`) lies within `reach_mm` of them by `distance_mm` (world point -> distance to the jaws' body) and
    /// they do not hold it already. They clamp it where it lies. A needle other jaws hold passes to these, hand
    /// to hand: the newest jaws to close on it hold it, and the others hold nothing from then on (they let go
    /// of nothing when they open). `in_tissue`: the needle runs through tissue now. Returns the angle from the
    /// tail where they hold it, rad.
    pub fn take(
        &mut self,
        tool: Option<u16>,
        world_from_tool: &Isometry3<f32>,
        arc: &NeedleArc,
        distance_mm: impl Fn(&Vec3) -> f32,
        reach_mm: f32,
        in_tissue: bool,
    ) -> Option<f32> {
        let theirs = match (self.holder, tool) {
            (NeedleHolder::Driver { .. }, None) => true,
            (NeedleHolder::Tool { tool: held_by, .. }, Some(k)) => held_by == k,
            _ => false,
        };
        if theirs || !finite(world_from_tool) {
            return None;
        }
        let (theta_rad, distance) = (0..=ARC_SAMPLES)
            .map(|k| {
                let theta = arc.sweep_rad() * k as f32 / ARC_SAMPLES as f32;
                let point = self.world_from_needle * Point3::from(arc.at(theta).point_mm);
                (theta, distance_mm(&point.coords))
            })
            .filter(|(_, d)| d.is_finite())
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        if distance > reach_mm {
            return None;
        }
        let tool_from_needle = world_from_tool.inverse() * self.world_from_needle;
        self.holder = match tool {
            None => NeedleHolder::Driver { tool_from_needle },
            Some(tool) => NeedleHolder::Tool {
                tool,
                tool_from_needle,
            },
        };
        self.regrasps += 1;
        self.taken_in_tissue = in_tissue;
        Some(theta_rad)
    }
}

fn finite(pose: &Isometry3<f32>) -> bool {
    pose.translation.vector.iter().all(|c| c.is_finite())
        && pose.rotation.coords.iter().all(|c| c.is_finite())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;

    fn at(x: f32, y: f32, z: f32) -> Isometry3<f32> {
        Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
    }

    #[test]
    fn a_needle_follows_its_holder_and_stays_where_it_is_let_go() {
        let arc = NeedleArc::new(10.0, 180.0).unwrap();
        let mut hold = NeedleHold::in_driver(at(0.0, 10.0, 0.0), &at(0.0, 0.0, 0.0));
        assert!(hold.in_drivers_jaws());
        hold.place(&at(5.0, 0.0, 0.0), |_| None);
        assert_eq!(
            hold.world_from_needle().translation.vector,
            Vec3::new(5.0, 10.0, 0.0)
        );
        // Hand to hand: jaws that hold it do not take it again; a grasper's jaws closing on it take it from the
        // driver where it lies, and the driver's take it back.
        let tip = hold.world_from_needle() * Point3::from(arc.tip().point_mm);
        let near_tip = |p: &Vec3| (p - tip.coords).norm();
        let driver = at(5.0, 0.0, 0.0);
        assert!(
            hold.take(None, &driver, &arc, near_tip, 1.0, false)
                .is_none()
        );
        let held_at = *hold.world_from_needle();
        assert!(
            hold.take(Some(1), &at(0.0, 0.0, 0.0), &arc, near_tip, 1.0, false)
                .is_some()
        );
        assert!(hold.held_by(1) && !hold.in_drivers_jaws());
        assert_eq!(*hold.world_from_needle(), held_at);
        assert!(
            hold.take(Some(1), &at(0.0, 0.0, 0.0), &arc, near_tip, 1.0, false)
                .is_none()
        );
        // The driver's jaws opening let go of nothing now; closing again, they take it back.
        assert!(!hold.let_go(None));
        assert!(
            hold.take(None, &driver, &arc, near_tip, 1.0, false)
                .is_some()
        );
        assert!(hold.in_drivers_jaws() && !hold.held_by(1));
        hold.place(&driver, |_| None);
        let moved = hold.world_from_needle().translation.vector - held_at.translation.vector;
        assert!(moved.norm() < 1e-4, "{moved:?}");
        // Let go, it stays put whatever the driver does.
        assert!(!hold.let_go(Some(1)));
        assert!(hold.let_go(None));
        hold.place(&at(50.0, 0.0, 0.0), |_| None);
        assert_eq!(
            hold.world_from_needle().translation.vector,
            Vec3::new(5.0, 10.0, 0.0)
        );
        // Jaws too far from every point of it do not take it; jaws at its tip take it there, as it lies.
        let far = |p: &Vec3| (p - tip.coords).norm() + 3.0;
        assert!(
            hold.take(Some(1), &at(0.0, 0.0, 0.0), &arc, far, 1.0, true)
                .is_none()
        );
        let jaws = at(tip.x, tip.y, tip.z);
        let theta = hold
            .take(Some(1), &jaws, &arc, near_tip, 1.0, true)
            .unwrap();
        assert!((theta - arc.sweep_rad()).abs() < 1e-6, "{theta}");
        assert!(hold.held_by(1) && hold.taken_in_tissue() && hold.regrasps() == 3);
        // It then follows tool 1, and its tip stays in the jaws.
        let moved = at(tip.x + 2.0, tip.y, tip.z - 1.0);
        hold.place(&at(0.0, 0.0, 0.0), |k| (k == 1).then_some(moved));
        let tip_now = hold.world_from_needle() * Point3::from(arc.tip().point_mm);
        assert!((tip_now.coords - moved.translation.vector).norm() < 1e-4);
        // Tool 1 leaving lets it go where it was; a NaN pose never moves it.
        assert!(hold.place(&at(0.0, 0.0, 0.0), |_| None));
        assert!(!hold.taken_in_tissue());
        let nan = at(f32::NAN, 0.0, 0.0);
        assert!(
            hold.take(None, &nan, &arc, near_tip, 100.0, false)
                .is_none()
        );
        let before = *hold.world_from_needle();
        hold.place(&nan, |_| None);
        assert_eq!(*hold.world_from_needle(), before);
    }
}

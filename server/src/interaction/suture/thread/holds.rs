//! What holds the thread besides its needle: a tool's jaws ([`SutureThread::take_grip`]) and the holes and the
//! track's rings it runs through ([`SutureThread::take_hole`]), taken and let go.
//!
//! Owns: the thread's grips and holes as sets (which node a grip takes, when a hole is taken or let go). How a
//! grip or a hole then holds its node is `thread_grip.rs` and `thread_hole.rs`; tearing at a hole is `tear.rs`.
//!
//! Must not: allocate beyond the sets' capacities.

use nalgebra::UnitQuaternion;

use super::SutureThread;
use crate::interaction::suture::thread_grip::{MAX_GRIPS, ThreadGrip, in_tool_frame};
use crate::interaction::suture::thread_hole::{HolePoint, ThreadHole};
use crate::interaction::suture::{MAX_HOLES, SurfacePoint};
use crate::tissue::Vec3;

impl SutureThread {
    /// Tool `tool`'s jaws, at `position_mm`, `rotation`, take the thread: the free node nearest them
    /// (`distance_mm` from the jaws) within `reach_mm`, held where it is now in the tool's frame. Not the
    /// tail's node, one a hole holds, or one another grip holds. Returns the node taken (None: none in reach,
    /// the tool already holds it, or [`MAX_GRIPS`] grips already). No allocation.
    pub fn take_grip(
        &mut self,
        tool: u16,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        distance_mm: impl Fn(&Vec3) -> f32,
        reach_mm: f32,
    ) -> Option<u32> {
        if self.grips.len() >= MAX_GRIPS
            || self.grips.iter().any(|g| g.tool == tool)
            || !self.is_laid_out()
        {
            return None;
        }
        let chain = &self.chain;
        let (node, _) = chain
            .positions_mm
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                chain.inverse_mass_per_kg()[*i] > 0.0
                    && !self
                        .holes
                        .iter()
                        .chain(&self.tracks)
                        .any(|h| h.holds_node(*i))
            })
            .map(|(i, p)| (i, distance_mm(p)))
            .filter(|(_, d)| *d <= reach_mm)
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        let at_tool_mm = in_tool_frame(&self.chain.positions_mm[node], position_mm, rotation);
        if !at_tool_mm.iter().all(|c| c.is_finite()) {
            return None;
        }
        self.chain.set_held(node, true, 0.0);
        self.grips
            .push(ThreadGrip::new(tool, node as u32, at_tool_mm));
        Some(node as u32)
    }

    /// Tool `tool`'s jaws let go of the thread. Returns whether they held it.
    pub fn release_grip(&mut self, tool: u16) -> bool {
        let before = self.grips.len();
        self.keep_grips(|g, _| g.tool != tool);
        self.grips.len() != before
    }

    /// Keep the grips `keep` says to (it may move the chain's nodes); each other lets go of its node, which
    /// gets its mass back. The one way a grip is let go. No allocation.
    pub(super) fn keep_grips(
        &mut self,
        mut keep: impl FnMut(&mut ThreadGrip, &mut crate::interaction::suture::ThreadChain) -> bool,
    ) {
        let node_mass_kg = self.node_mass_kg();
        let chain = &mut self.chain;
        self.grips.retain_mut(|grip| {
            let kept = keep(grip, chain);
            if !kept {
                chain.set_held(grip.node as usize, false, node_mass_kg);
            }
            kept
        });
    }

    /// The jaws holding it.
    pub fn grips(&self) -> &[ThreadGrip] {
        &self.grips
    }

    /// Tool `tool`'s grip on it, if it holds it.
    pub fn grip_of(&self, tool: u16) -> Option<&ThreadGrip> {
        self.grips.iter().find(|g| g.tool == tool)
    }

    /// A hole the needle's tail just left takes the thread there (at its tail, `u = 0`): `squeeze_n`,
    /// `friction` and `stiffness_n_per_mm` as [`ThreadHole::new`]. False when the thread already runs through
    /// [`MAX_HOLES`] holes (the hole is then let go).
    pub fn take_hole(
        &mut self,
        point: SurfacePoint,
        squeeze_n: f32,
        friction: f32,
        stiffness_n_per_mm: f32,
    ) -> bool {
        if self.holes.len() >= MAX_HOLES {
            return false;
        }
        self.holes.push(ThreadHole::new(
            HolePoint::Surface(point),
            0.0,
            squeeze_n,
            friction,
            stiffness_n_per_mm,
        ));
        true
    }

    /// Object `object` was subdivided: the holes, the tracks' rings and the points the nodes lie on there are
    /// re-expressed on the pieces of their elements that hold them (the same places).
    pub fn subdivided(
        &mut self,
        object: usize,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        for hole in self.holes.iter_mut().chain(self.tracks.iter_mut()) {
            hole.point = hole.point.remapped(object, remap);
        }
        for contact in self.contacts.iter_mut().flatten() {
            *contact = contact.remapped(object, remap);
        }
    }

    /// The holes in the surface the thread runs through.
    pub fn holes(&self) -> &[ThreadHole] {
        &self.holes
    }

    /// The rings of the needle's tracks inside the tissue it runs through.
    pub fn tracks(&self) -> &[ThreadHole] {
        &self.tracks
    }

    /// Let go of the holes (and the tracks) in object `object` (it was reset, or its topology changed under
    /// them is handled by each hole's place); all of them for `None`. Returns how many holes.
    pub fn release_holes(&mut self, object: Option<usize>) -> u32 {
        let before = self.holes.len();
        let kept = |h: &ThreadHole| object.is_some_and(|o| usize::from(h.point.object()) != o);
        self.holes.retain(kept);
        self.tracks.retain(kept);
        (before - self.holes.len()) as u32
    }
}

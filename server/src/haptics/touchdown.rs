//! A touch-down before a tool's first contact: which surface nodes the tool would hold if it touched the plane
//! it approaches (its footprint), and the bookkeeping of the contact-stiffness solve run on them.
//!
//! Owns: [`Touchdown`] (per tool and object: the footprint, the solve due in the tick's tail, the node of the
//! last finished one, whether the solver holds a touch-down) and [`TOUCHDOWN_DEPTH_PER_REACH`]. The plane carries
//! the solve's normal stiffness (`sim::tool_output`), so a distant hand meets the tissue's own stiffness at
//! first touch rather than a fixed prior.
//!
//! Must not: run the solve (the solver's driver does, in `Sim::finish_tick`) or allocate beyond the capacity
//! it is built with.

use crate::tissue::Vec3;

/// A touch-down's footprint is the plane's node and the surface nodes inside the tool moved straight down the
/// plane's normal until it presses past touching the plane by this fraction of its reach along the normal (a
/// sphere's radius): what the tool holds in the first round trip of a contact, a patch of two thirds of a
/// sphere's radius. Before a tool's first contact, each plane carries the contact-stiffness solve of this
/// footprint held (the tool's normal into the tissue), in the tick's tail: the stiffness the tissue will show
/// at first touch. A fixed prior (0.2 N/mm) was six times too stiff on a loosely held sheet; a fixed 2.5 mm
/// footprint (twenty of the pad's nodes) was right for a 4 mm probe but six times too stiff for a 1.5 mm
/// cautery tip, whose contact shows 0.029 N/mm pressed 1 mm and whose peak at a distance was +318%. The tip's
/// footprint is now one node (0.008 N/mm): softer than its contact, never stiffer. Whole nodes make it coarse;
/// scaling the solve by the patch's area over the held nodes' brought the tip's plane to 0.019 N/mm but the
/// light hand's touch-down on the pad to +10.9% at 200 ms (from +6.2%), so it was not kept.
pub const TOUCHDOWN_DEPTH_PER_REACH: f32 = 0.25;

/// Most nodes in a touch-down's footprint.
pub const TOUCHDOWN_MAX_NODES: usize = 64;

/// One tool's touch-down on one object.
#[derive(Debug)]
pub struct Touchdown {
    /// The plane's node and outward normal of a solve due in the tick's tail, if one is.
    pub due: Option<(u32, Vec3)>,
    /// The plane's node of the last finished solve.
    pub node: Option<u32>,
    /// The solver works on (or holds) a touch-down; a contact starts its own solve afresh.
    pub active: bool,
    /// The footprint's nodes (the plane's node first).
    pub held: Vec<u32>,
    /// The tool's normals at the footprint's nodes (into the tissue).
    pub normals: Vec<Vec3>,
}

impl Default for Touchdown {
    fn default() -> Self {
        Self {
            due: None,
            node: None,
            active: false,
            held: Vec::with_capacity(TOUCHDOWN_MAX_NODES),
            normals: Vec::with_capacity(TOUCHDOWN_MAX_NODES),
        }
    }
}

impl Touchdown {
    /// A solve is wanted for the plane through `node`: none has finished for it (or the solver has none).
    pub fn wants(&self, node: u32, solver_has_result: bool) -> bool {
        self.node != Some(node) || !solver_has_result
    }

    /// Queue a solve for the plane through `node` with outward `normal`: its footprint is `node` and the
    /// `candidates` (`positions_mm` indexed by node) for which `in_footprint` holds (the caller's test: inside
    /// the tool pressed [`TOUCHDOWN_DEPTH_PER_REACH`] of its reach past the plane), up to the capacity. No allocation.
    pub fn queue(
        &mut self,
        node: u32,
        normal: Vec3,
        candidates: &[u32],
        positions_mm: &[Vec3],
        in_footprint: impl Fn(&Vec3) -> bool,
    ) {
        self.due = Some((node, normal));
        self.active = true;
        self.held.clear();
        self.normals.clear();
        self.held.push(node);
        self.normals.push(-normal);
        for &i in candidates {
            if self.held.len() == self.held.capacity() {
                break;
            }
            if i != node && positions_mm.get(i as usize).is_some_and(&in_footprint) {
                self.held.push(i);
                self.normals.push(-normal);
            }
        }
    }

    /// The contact began: forget the touch-down (the caller drops the solver's result). True if one was in
    /// play.
    pub fn end(&mut self) -> bool {
        self.node = None;
        std::mem::take(&mut self.active)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_footprint_is_the_node_and_the_candidates_near_it() {
        let x: Vec<Vec3> = (0..6).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let mut t = Touchdown::default();
        assert!(t.wants(2, true));
        t.queue(2, Vec3::z(), &[0, 1, 2, 3, 4, 5], &x, |p| {
            (p - Vec3::new(2.0, 0.0, 0.0)).norm() <= 2.5
        });
        assert_eq!(t.held, vec![2, 0, 1, 3, 4]);
        assert!(t.normals.iter().all(|n| *n == -Vec3::z()));
        assert_eq!(t.due, Some((2, Vec3::z())));
        t.node = Some(2);
        assert!(!t.wants(2, true) && t.wants(2, false) && t.wants(3, true));
        assert!(t.end() && !t.end() && t.node.is_none());
    }
}

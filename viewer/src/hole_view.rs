//! kiss3d nodes for the punctures of the suture threads' needles (protocol 18's `ThreadState::holes`): one small
//! sphere at each hole, coloured by how hard what runs through it pulls on the tissue there, so an instructor
//! sees where each bite went in and came out and which stitch is drawn tight.
//!
//! Owns: [`HoleView`], the holes' look ([`HoleView::RADIUS_MM`], [`hole_rgb`]) and keeping their nodes in step
//! with the [`sinew_protocol::ThreadState`]s. Nodes are added when holes appear and hidden (kept for reuse) when
//! they go, so a steady stitch moves and recolours its nodes in place.
//!
//! Must not: create windows, or outlive the group it drew into (the scene view drops it with the group).

use kiss3d::color::Color;
use kiss3d::glamx::Vec3;
use kiss3d::scene::SceneNode3d;
use sinew_protocol::{HoleMark, ThreadState};

/// A hole with nothing pulling: dark, as a fresh puncture in skin looks.
pub const SLACK_RGB: [f32; 3] = [0.16, 0.03, 0.05];
/// A hole pulled at [`TIGHT_N`] or more: amber, a stitch drawn as tight as skin bears.
pub const TIGHT_RGB: [f32; 3] = [1.0, 0.72, 0.08];
/// The pull drawn as [`TIGHT_RGB`], N (skin-like material tears at a hole at about 3.3-4.1 N).
pub const TIGHT_N: f32 = 3.3;

/// The colour a hole is drawn in, linear RGB: [`SLACK_RGB`] at no pull through to [`TIGHT_RGB`] at [`TIGHT_N`]
/// (a pull that is not finite draws as tight).
pub fn hole_rgb(hole: &HoleMark) -> [f32; 3] {
    let t = if hole.pull_n.is_finite() {
        (hole.pull_n / TIGHT_N).clamp(0.0, 1.0)
    } else {
        1.0
    };
    std::array::from_fn(|i| SLACK_RGB[i] + (TIGHT_RGB[i] - SLACK_RGB[i]) * t)
}

/// Every hole's node, over all threads, in the threads' order then each thread's holes' order.
#[derive(Default)]
pub struct HoleView {
    nodes: Vec<SceneNode3d>,
    shown: usize,
}

impl HoleView {
    /// Radius a hole is drawn with, mm: wider than the thread ([`crate::thread_view::ThreadView::RADIUS_MM`])
    /// so the mark shows round it.
    pub const RADIUS_MM: f32 = 1.0;

    /// Draw the holes of `threads` into `group`: add nodes while there are more holes than nodes, place and
    /// colour one per hole, hide the rest.
    pub fn sync(&mut self, group: &mut SceneNode3d, threads: &[ThreadState]) {
        let holes = threads.iter().flat_map(|thread| &thread.holes);
        let wanted = holes.clone().count();
        while self.nodes.len() < wanted {
            self.nodes.push(
                group
                    .add_sphere(Self::RADIUS_MM)
                    .set_roughness(0.8)
                    .set_metallic(0.0)
                    .set_visible(false),
            );
        }
        for (node, hole) in self.nodes.iter_mut().zip(holes) {
            let at = Vec3::from(hole.position_mm);
            if !at.is_finite() {
                node.set_visible(false);
                continue;
            }
            let [r, g, b] = hole_rgb(hole);
            node.set_position(at)
                .set_color(Color::new(r, g, b, 1.0))
                .set_visible(true);
        }
        for node in self.nodes.iter_mut().skip(wanted) {
            node.set_visible(false);
        }
        self.shown = wanted;
    }

    /// Holes drawn.
    pub fn shown(&self) -> usize {
        self.shown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hole_goes_from_dark_to_amber_as_its_stitch_is_drawn_tight() {
        let at = |pull_n| {
            hole_rgb(&HoleMark {
                pull_n,
                ..HoleMark::default()
            })
        };
        assert_eq!(at(0.0), SLACK_RGB);
        assert_eq!(at(TIGHT_N), TIGHT_RGB);
        assert_eq!(at(10.0), TIGHT_RGB);
        assert_eq!(at(f32::NAN), TIGHT_RGB);
        let half = at(0.5 * TIGHT_N);
        for i in 0..3 {
            let mid = 0.5 * (SLACK_RGB[i] + TIGHT_RGB[i]);
            assert!((half[i] - mid).abs() < 1e-6, "{half:?}");
        }
    }
}

//! kiss3d nodes for the suture threads of a replica's tool states: one thin capsule per segment of each
//! thread's polyline, placed and stretched to the segment every frame.
//!
//! Owns: [`ThreadView`], the threads' look ([`THREAD_COLOUR`], [`ThreadView::RADIUS_MM`]) and keeping their
//! nodes in step with [`sinew_protocol::ThreadState`]s. Nodes are rebuilt only when the threads' number or
//! their node counts change; otherwise each segment's node is moved, turned and stretched in place.
//!
//! Must not: create windows, or outlive the group it drew into (the scene view drops it with the group).

use kiss3d::color::Color;
use kiss3d::glamx::{Quat, Vec3};
use kiss3d::scene::SceneNode3d;
use sinew_protocol::ThreadState;

/// Suture violet (dyed polyglactin), distinct from tissue and steel.
pub const THREAD_COLOUR: Color = Color::new(0.42, 0.20, 0.78, 1.0);

/// The drawn segments of one thread.
struct ThreadNodes {
    tool: u16,
    segments: Vec<SceneNode3d>,
}

/// Every thread's nodes.
#[derive(Default)]
pub struct ThreadView {
    threads: Vec<ThreadNodes>,
    /// One thread's nodes dequantized, mm (reused).
    scratch: Vec<Vec3>,
}

impl ThreadView {
    /// Radius a thread is drawn with, mm: thicker than a 3-0 suture (0.2-0.25 mm across) so it stays a few
    /// pixels wide in a view of the whole scene.
    pub const RADIUS_MM: f32 = 0.35;

    /// Draw `threads` into `group`: rebuild the nodes if the threads' layout changed, then place every segment.
    pub fn sync(&mut self, group: &mut SceneNode3d, threads: &[ThreadState]) {
        let same_layout = self.threads.len() == threads.len()
            && self.threads.iter().zip(threads).all(|(drawn, thread)| {
                drawn.tool == thread.tool
                    && drawn.segments.len() == thread.nodes_q.len().saturating_sub(1)
            });
        if !same_layout {
            self.clear();
            self.threads = threads
                .iter()
                .map(|thread| ThreadNodes {
                    tool: thread.tool,
                    segments: (1..thread.nodes_q.len())
                        .map(|_| {
                            group
                                .add_capsule(Self::RADIUS_MM, 1.0)
                                .set_color(THREAD_COLOUR)
                                .set_roughness(0.6)
                                .set_metallic(0.0)
                                .set_visible(false)
                        })
                        .collect(),
                })
                .collect();
        }
        for (drawn, thread) in self.threads.iter_mut().zip(threads) {
            self.scratch.clear();
            self.scratch.extend(thread.nodes_mm().map(Vec3::from));
            for (node, pair) in drawn.segments.iter_mut().zip(self.scratch.windows(2)) {
                place_segment(node, pair[0], pair[1]);
            }
        }
    }

    /// Remove every node (the threads are gone, or the group is about to be rebuilt).
    pub fn clear(&mut self) {
        for thread in &mut self.threads {
            for node in &mut thread.segments {
                node.remove();
            }
        }
        self.threads.clear();
    }

    /// Segments drawn, over all threads.
    pub fn segments(&self) -> usize {
        self.threads.iter().map(|t| t.segments.len()).sum()
    }
}

/// Put a unit capsule (kiss3d's run along y) on the segment from `a` to `b`, stretched to its length; a
/// segment of no length (or not finite) is hidden.
fn place_segment(node: &mut SceneNode3d, a: Vec3, b: Vec3) {
    let along = b - a;
    let length_mm = along.length();
    if !length_mm.is_finite() || length_mm < 1e-4 {
        node.set_visible(false);
        return;
    }
    node.set_position(0.5 * (a + b))
        .set_rotation(Quat::from_rotation_arc(Vec3::Y, along / length_mm))
        .set_local_scale(1.0, length_mm, 1.0)
        .set_visible(true);
}

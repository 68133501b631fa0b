//! Tool states: server -> viewers.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};
use crate::quantize::QuantBounds;

/// One tool's state in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ToolState {
    /// Tool index (matches [`crate::ToolInfo::tool`]).
    pub tool: u16,
    /// Tool origin in the world, mm.
    pub position_mm: [f32; 3],
    /// Tool orientation in the world, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// Force the tissue exerts on the tool, newtons, world frame.
    pub force_n: [f32; 3],
    /// A device is bound and sending poses (false: released, it does not touch the tissue).
    pub active: bool,
    /// The tool touches tissue.
    pub in_contact: bool,
    /// A grasper's jaw opening, rad (0 closed; 0 for a probe). Protocol 6.
    pub jaw_angle_rad: f32,
    /// Points of tissue the jaws hold (0: not grasping). Protocol 6.
    pub attachments: u16,
}

/// A suture thread as it lies: the polyline from the tail of a needle (the tool that carries it) to its free
/// end, quantized like a mesh in bounds of its own (a quantum is the bounds' extent / 65535 per axis: 0.002 mm
/// across a 150 mm thread). Protocol 14.
#[derive(Debug, PartialEq, Serialize, Deserialize)]
pub struct ThreadState {
    /// The tool whose needle carries the thread (matches [`crate::ToolInfo::tool`]).
    pub tool: u16,
    /// The nodes' quantization bounds, world mm: their box, grown by [`ThreadState::MARGIN_MM`] each way.
    pub bounds: QuantBounds,
    /// The thread's nodes from the needle's tail to the free end, quantized in `bounds`.
    pub nodes_q: Vec<[u16; 3]>,
    /// The punctures in the tissue's surface that belong to this thread's needle: the holes the thread runs
    /// through (the stitches), then the holes the needle itself still passes through. Protocol 18.
    pub holes: Vec<HoleMark>,
}

/// A puncture in a tissue's surface, made by a needle: a viewer marks it, so a watching instructor sees where
/// each bite went in and came out and how hard the stitch pulls there. Protocol 18.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct HoleMark {
    /// Where the hole is now, world mm (the punctured material point of the surface, as the tissue moved it).
    pub position_mm: [f32; 3],
    /// How hard what runs through it pulls on the tissue there, N (the thread's pull for a stitch's hole, the
    /// needle's for a hole on the needle): a viewer shows a stitch drawn tight.
    pub pull_n: f32,
    /// The needle still passes through it (the thread has not reached it yet).
    pub on_needle: bool,
}

impl ThreadState {
    /// Most nodes one thread may have (a 512-segment thread has 513).
    pub const MAX_NODES: usize = 1024;
    /// Most holes one thread may carry (a running suture of 64 stitches, with the needle's own).
    pub const MAX_HOLES: usize = 256;
    /// How far the bounds reach past the nodes' box, mm (so a straight thread's bounds have extent).
    pub const MARGIN_MM: f32 = 0.5;
    /// Bounds of a thread with no finite node on an axis (valid, and never used to place a node).
    const EMPTY_BOUNDS: QuantBounds = QuantBounds {
        min_mm: [0.0; 3],
        max_mm: [1.0; 3],
    };

    /// The thread of tool `tool` with these nodes (world mm).
    pub fn from_nodes_mm(tool: u16, nodes_mm: &[[f32; 3]]) -> Self {
        let mut thread = Self::default();
        thread.set(tool, nodes_mm.iter().copied());
        thread
    }

    /// Quantize `nodes_mm` (world mm) into this message, reusing its buffer (no allocation once it has held
    /// as many nodes). Non-finite coordinates land on the bounds' corner. The holes are cleared: push this
    /// frame's after.
    pub fn set(&mut self, tool: u16, nodes_mm: impl Iterator<Item = [f32; 3]> + Clone) {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in nodes_mm.clone() {
            for a in 0..3 {
                if p[a].is_finite() {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
        }
        let mut bounds = Self::EMPTY_BOUNDS;
        for a in 0..3 {
            if lo[a] <= hi[a] {
                bounds.min_mm[a] = lo[a] - Self::MARGIN_MM;
                bounds.max_mm[a] = hi[a] + Self::MARGIN_MM;
            }
        }
        self.tool = tool;
        self.bounds = bounds;
        self.nodes_q.clear();
        self.nodes_q.extend(nodes_mm.map(|p| bounds.quantize(p).0));
        self.holes.clear();
    }

    /// The nodes, world mm (dequantized).
    pub fn nodes_mm(&self) -> impl ExactSizeIterator<Item = [f32; 3]> + '_ {
        self.nodes_q.iter().map(|&q| self.bounds.dequantize(q))
    }
}

impl Default for ThreadState {
    fn default() -> Self {
        Self {
            tool: 0,
            bounds: Self::EMPTY_BOUNDS,
            nodes_q: Vec::new(),
            holes: Vec::new(),
        }
    }
}

impl Clone for ThreadState {
    fn clone(&self) -> Self {
        Self {
            tool: self.tool,
            bounds: self.bounds,
            nodes_q: self.nodes_q.clone(),
            holes: self.holes.clone(),
        }
    }

    /// Reuses the nodes' and holes' buffers (the publish thread copies every frame's threads).
    fn clone_from(&mut self, source: &Self) {
        self.tool = source.tool;
        self.bounds = source.bounds;
        self.nodes_q.clone_from(&source.nodes_q);
        self.holes.clone_from(&source.holes);
    }
}

/// Where a needle driver's needle lies, whoever holds it: the pose at which its driver's jaws would hold it as
/// loaded (so a viewer draws it with [`crate::needle_point_in_tool_mm`] in this frame, as it draws a needle in
/// its driver's jaws). In its driver's jaws as loaded this is the driver's own pose; let go in the tissue, or
/// taken by a grasper, it is where the needle is. Protocol 15.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct NeedleState {
    /// The needle driver whose needle it is (matches [`crate::ToolInfo::tool`]).
    pub tool: u16,
    /// The frame's origin in the world, mm.
    pub position_mm: [f32; 3],
    /// The frame's orientation in the world, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
}

/// The state of every tool at one publish frame.
///
/// Direction: server -> viewers, on `sinew/<scene>/tools`. Rate: every publish frame (~60 Hz); doubles as the
/// scene heartbeat. Reliability: best effort (the next frame replaces it). Units: mm, newtons, seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ToolStates {
    /// Publish frame.
    pub frame: u64,
    /// Simulated time, seconds.
    pub sim_time_s: f64,
    /// One entry per tool, in tool order.
    pub tools: Vec<ToolState>,
    /// Every suture thread in the scene, in the order of the tools that carry them (empty for none).
    /// Protocol 14.
    pub threads: Vec<ThreadState>,
    /// Every needle driver's needle, in tool order. Protocol 15.
    pub needles: Vec<NeedleState>,
}

impl ToolStates {
    /// Most threads (and needles) one message may carry.
    pub const MAX_THREADS: usize = 64;
}

impl Message for ToolStates {
    const KIND: MessageKind = MessageKind::ToolStates;
    fn validate(&self) -> Result<(), FieldError> {
        if !self.sim_time_s.is_finite() {
            return Err(("sim_time_s", "not finite"));
        }
        for tool in &self.tools {
            check::finite("tools.position_mm", &tool.position_mm)?;
            check::unit_quaternion("tools.orientation_xyzw", &tool.orientation_xyzw)?;
            check::finite("tools.force_n", &tool.force_n)?;
            check::finite("tools.jaw_angle_rad", &[tool.jaw_angle_rad])?;
            if !(0.0..=std::f32::consts::PI).contains(&tool.jaw_angle_rad) {
                return Err(("tools.jaw_angle_rad", "outside 0 to pi"));
            }
        }
        if self.threads.len() > Self::MAX_THREADS {
            return Err(("threads", "more than 64 threads"));
        }
        for thread in &self.threads {
            thread
                .bounds
                .validate()
                .map_err(|_| ("threads.bounds", "not finite, or max not above min"))?;
            if thread.nodes_q.len() > ThreadState::MAX_NODES {
                return Err(("threads.nodes_q", "more than 1024 nodes"));
            }
            if thread.holes.len() > ThreadState::MAX_HOLES {
                return Err(("threads.holes", "more than 256 holes"));
            }
            for hole in &thread.holes {
                check::finite("threads.holes.position_mm", &hole.position_mm)?;
                check::finite("threads.holes.pull_n", &[hole.pull_n])?;
                if hole.pull_n < 0.0 {
                    return Err(("threads.holes.pull_n", "negative"));
                }
            }
        }
        if self.needles.len() > Self::MAX_THREADS {
            return Err(("needles", "more than 64 needles"));
        }
        for needle in &self.needles {
            check::finite("needles.position_mm", &needle.position_mm)?;
            check::unit_quaternion("needles.orientation_xyzw", &needle.orientation_xyzw)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_comes_back_within_its_quantum_even_straight_and_with_a_bad_node() {
        let nodes: Vec<[f32; 3]> = (0..65)
            .map(|i| [-80.0 + 2.3 * i as f32, 4.0, 1.0])
            .collect();
        let mut thread = ThreadState::from_nodes_mm(3, &nodes);
        assert_eq!(thread.tool, 3);
        let bound = thread.bounds.max_error_mm();
        assert!(bound < 0.003, "{bound} mm");
        // On the wire: smaller than the nodes as f32 (postcard writes a u16 in 1-3 bytes).
        let alone = ToolStates::default();
        let with = ToolStates {
            threads: vec![thread.clone()],
            ..ToolStates::default()
        };
        let encoded = |m: &ToolStates| crate::codec::encode_to_vec(crate::InstanceId(1), m).len();
        let bytes = encoded(&with) - encoded(&alone);
        println!("a 65-node thread takes {bytes} bytes ({} as f32)", 65 * 12);
        assert!(bytes < 65 * 12, "{bytes} bytes");
        for (back, sent) in thread.nodes_mm().zip(&nodes) {
            let error = (0..3)
                .map(|a| (back[a] - sent[a]).powi(2))
                .sum::<f32>()
                .sqrt();
            assert!(error <= bound, "{back:?} vs {sent:?}: {error} > {bound} mm");
        }
        // Set again with fewer nodes, one not finite: the buffer is reused and the message stays valid.
        let capacity = thread.nodes_q.capacity();
        let mut fewer = nodes[..10].to_vec();
        fewer[4] = [f32::NAN, 0.0, 1.0];
        thread.set(3, fewer.iter().copied());
        assert_eq!(
            (thread.nodes_q.len(), thread.nodes_q.capacity()),
            (10, capacity)
        );
        let states = ToolStates {
            threads: vec![thread],
            ..ToolStates::default()
        };
        assert_eq!(states.validate(), Ok(()));
    }

    #[test]
    fn a_threads_holes_are_cleared_by_set_and_a_bad_hole_is_refused_by_name() {
        let mut thread = ThreadState::from_nodes_mm(0, &[[0.0; 3], [2.0, 0.0, 0.0]]);
        let hole = HoleMark {
            position_mm: [1.0, 0.0, -0.2],
            pull_n: 1.5,
            on_needle: false,
        };
        thread.holes.push(hole);
        let with = |thread: &ThreadState| ToolStates {
            threads: vec![thread.clone()],
            ..ToolStates::default()
        };
        assert_eq!(with(&thread).validate(), Ok(()));
        for (bad, field) in [
            (
                HoleMark {
                    position_mm: [f32::NAN, 0.0, 0.0],
                    ..hole
                },
                "threads.holes.position_mm",
            ),
            (
                HoleMark {
                    pull_n: f32::INFINITY,
                    ..hole
                },
                "threads.holes.pull_n",
            ),
            (
                HoleMark {
                    pull_n: -1.0,
                    ..hole
                },
                "threads.holes.pull_n",
            ),
        ] {
            let mut wrong = thread.clone();
            wrong.holes.push(bad);
            assert!(
                matches!(with(&wrong).validate(), Err((f, _)) if f == field),
                "{bad:?}"
            );
        }
        let mut many = thread.clone();
        many.holes = vec![hole; ThreadState::MAX_HOLES + 1];
        assert!(matches!(with(&many).validate(), Err(("threads.holes", _))));
        // The next frame's `set` starts its holes afresh (the buffer kept).
        thread.set(0, [[0.0; 3]].into_iter());
        assert!(thread.holes.is_empty() && thread.holes.capacity() >= 1);
    }
}

//! The sim thread's hand-off of a frame (positions, tool states) to the publish thread.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use sinew_protocol::{HoleMark, NeedleState, ThreadState, ToolState};

use crate::sim::{Sim, ToolOutput};

/// One frame of the scene as the sim left it.
#[derive(Debug, Clone)]
pub struct FrameData {
    /// Sim ticks at capture.
    pub tick: u64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Positions per object, mm.
    pub positions_mm: Vec<Vec<crate::tissue::Vec3>>,
    /// Burn level per object and node, 0-255.
    pub burn: Vec<Vec<u8>>,
    /// Tool states, tool order.
    pub tools: Vec<ToolState>,
    /// Connectivity per object (copied only when a cut or tear changed it).
    pub topology: Vec<crate::replication::ObjectTopology>,
    /// The suture threads laid out, in the order of the tools that carry them.
    pub threads: Vec<ThreadState>,
    /// Where each needle driver's needle lies, in tool order.
    pub needles: Vec<NeedleState>,
}

/// A single-slot exchange: the sim thread `try_offer`s (never blocks), the publisher `take`s.
#[derive(Debug)]
pub struct FrameExchange {
    slot: Mutex<FrameData>,
    offered: AtomicU64,
}

impl FrameExchange {
    /// Buffers sized for `sim`.
    pub fn new(sim: &Sim) -> Self {
        Self {
            slot: Mutex::new(FrameData {
                tick: 0,
                sim_time_s: 0.0,
                positions_mm: sim
                    .objects
                    .iter()
                    .map(|o| o.state.positions_mm.clone())
                    .collect(),
                burn: sim
                    .objects
                    .iter()
                    .map(|o| vec![0; o.burn().len()])
                    .collect(),
                tools: vec![ToolState::default(); sim.tools.len()],
                topology: sim
                    .objects
                    .iter()
                    .map(|o| {
                        let mut t = crate::replication::ObjectTopology::default();
                        t.follow(o);
                        t
                    })
                    .collect(),
                // Filled once a thread is laid out (its tool driven): none is at the first offer.
                threads: Vec::new(),
                needles: Vec::with_capacity(sim.tools.len()),
            }),
            offered: AtomicU64::new(0),
        }
    }

    /// Copy the sim's current frame in. Returns false (nothing written) if the publisher holds the slot.
    /// Real-time contract: never blocks; no allocation, except on the first offer after a cut or tear grew an
    /// object.
    pub fn try_offer(&self, sim: &Sim, outputs: &[ToolOutput]) -> bool {
        let Ok(mut frame) = self.slot.try_lock() else {
            return false;
        };
        frame.tick = sim.steps();
        frame.sim_time_s = sim.time_s();
        for (dst, object) in frame.positions_mm.iter_mut().zip(&sim.objects) {
            if dst.len() != object.state.positions_mm.len() {
                dst.resize(
                    object.state.positions_mm.len(),
                    crate::tissue::Vec3::zeros(),
                );
            }
            dst.copy_from_slice(&object.state.positions_mm);
        }
        for (dst, object) in frame.burn.iter_mut().zip(&sim.objects) {
            if dst.len() != object.burn().len() {
                dst.resize(object.burn().len(), 0);
            }
            for (level, burn) in dst.iter_mut().zip(object.burn()) {
                *level = (burn >> 8) as u8;
            }
        }
        for (dst, object) in frame.topology.iter_mut().zip(&sim.objects) {
            dst.follow(object);
        }
        for (t, (dst, tool)) in frame.tools.iter_mut().zip(&sim.tools).enumerate() {
            let q = tool.rotation.quaternion();
            let out = outputs.get(t).copied().unwrap_or_default();
            *dst = ToolState {
                tool: t as u16,
                position_mm: [tool.position_mm.x, tool.position_mm.y, tool.position_mm.z],
                orientation_xyzw: [q.i, q.j, q.k, q.w],
                force_n: [
                    out.force_world_n.x,
                    out.force_world_n.y,
                    out.force_world_n.z,
                ],
                active: tool.active,
                in_contact: out.in_contact,
                jaw_angle_rad: out.jaw_angle_rad,
                attachments: out.attachments,
            };
        }
        copy_threads(sim, &mut frame.threads);
        copy_needles(sim, &mut frame.needles);
        drop(frame);
        self.offered.fetch_add(1, Ordering::Release);
        true
    }

    /// Frames offered so far.
    pub fn offered(&self) -> u64 {
        self.offered.load(Ordering::Acquire)
    }

    /// Run `f` on the current frame (blocks the sim's next offer meanwhile, never the sim itself).
    pub fn with_frame<R>(&self, f: impl FnOnce(&FrameData) -> R) -> Option<R> {
        self.slot.lock().ok().map(|frame| f(&frame))
    }

    /// Copy of one object's latest positions, mm.
    pub fn latest_positions(&self, object: usize) -> Option<Vec<[f32; 3]>> {
        self.with_frame(|frame| {
            frame
                .positions_mm
                .get(object)
                .map(|ps| ps.iter().map(|p| [p.x, p.y, p.z]).collect())
        })
        .flatten()
    }
}

/// Where each needle driver's needle lies: the pose its driver's jaws would hold it at as loaded (the
/// protocol's [`NeedleState`]). No allocation (room for every tool was made).
fn copy_needles(sim: &Sim, needles: &mut Vec<NeedleState>) {
    needles.clear();
    for (t, tool) in sim.tools.iter().enumerate() {
        let (crate::interaction::InstrumentSpec::NeedleDriver(spec), Some(hold)) =
            (&tool.instrument, tool.needle_hold())
        else {
            continue;
        };
        let pose = hold.world_from_needle() * spec.tool_from_needle().inverse();
        let (p, q) = (pose.translation.vector, pose.rotation.quaternion());
        needles.push(NeedleState {
            tool: t as u16,
            position_mm: [p.x, p.y, p.z],
            orientation_xyzw: [q.i, q.j, q.k, q.w],
        });
    }
}

/// Quantize the threads laid out in `sim` into `threads`, each with its needle's holes in the surface (their
/// buffers reused: no allocation unless a thread appeared or grew, or a hole was made).
fn copy_threads(sim: &Sim, threads: &mut Vec<ThreadState>) {
    let mut n = 0;
    for (t, tool) in sim.tools.iter().enumerate() {
        let Some(thread) = tool.thread().filter(|thread| thread.is_laid_out()) else {
            continue;
        };
        if threads.len() == n {
            threads.push(ThreadState::default());
        }
        let dst = &mut threads[n];
        dst.set(t as u16, thread.nodes_mm().iter().map(|p| [p.x, p.y, p.z]));
        let stitches = thread.holes().iter().map(|hole| HoleMark {
            position_mm: hole.place_mm().into(),
            pull_n: hole.pull_on_tissue_n().norm(),
            on_needle: false,
        });
        let on_needle = tool.needle().into_iter().flat_map(|needle| {
            needle.holes().iter().filter_map(|hole| {
                let object = sim.objects.get(usize::from(hole.point.object))?;
                let at_mm = hole.point.position_mm(&object.model, &object.state)?;
                Some(HoleMark {
                    position_mm: at_mm.into(),
                    pull_n: hole.force_n.norm(),
                    on_needle: true,
                })
            })
        });
        dst.holes.extend(
            stitches
                .chain(on_needle)
                .filter(|mark| {
                    mark.position_mm.iter().all(|c| c.is_finite()) && mark.pull_n.is_finite()
                })
                .take(ThreadState::MAX_HOLES),
        );
        n += 1;
    }
    threads.truncate(n);
}

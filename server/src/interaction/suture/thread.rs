//! A suture thread swaged to a needle's tail: a chain of segments that follows the needle, hangs, bends a
//! little and lies on the tissue and against the tools without passing into them.
//!
//! Owns: [`ThreadSpec`] (length and segments, the world's keys), the thread's material constants and
//! [`SutureThread`] (the [`ThreadChain`] with its first node on the needle's tail, and each node's contact with
//! a surface). The needle driver steps it once a tick, after the tissue's substeps, in substeps of its own
//! (`sim/instruments/needle_driver.rs`). Placing it (laid out, laid along a path) is `thread/lay.rs`.
//!
//! A step:
//! - the tail node moves on a straight line from last tick's tail to this tick's, a substep at a time (it is
//!   held: it has no inverse mass);
//! - the chain predicts under gravity and drag, bends back a little ([`ThreadChain::set_bending`]) and is held
//!   to length by its direct solve, the holes it runs through holding their nodes inside that solve
//!   (`thread_hole.rs`), and so do the rings of the needle's track inside the tissue (`thread_track.rs`);
//! - **itself**: no two segments closer than its diameter, none passing through another
//!   (`thread_self_contact.rs`), before the contacts and once more after them;
//! - **jaws**: a grasper's jaws clamp the node they closed on as the tail is held, and move it with them
//!   (`thread_grip.rs`); the thread slips out of them past their hold;
//! - **edges**: a segment whose nodes lie outside the tissue but whose middle cuts across an edge or a corner
//!   of it goes back out round the edge (`thread_edge_contact.rs`), before the node contacts and after them;
//! - **tools**: a node within the thread's radius of a tool's tip or shaft (at its pose this tick) goes to that
//!   clearance by the nearest way out (`ToolCollider::keep_clear`), without friction (not a node a hole holds);
//!   one the tissue then puts back into the tool (pinched between the two) is moved along the tissue's
//!   surface, out from under the tool; then each segment whose middle lies within it (a node-only push lets a
//!   2.3 mm segment cut through a 3 mm jaw's rim) goes out whole (`thread_tool_contact.rs`: swept-sphere
//!   parts); the jaws holding a node leave that node and the two either side of it alone;
//! - **its needle**: a segment within the thread's radius of the needle's wire goes out across it to that
//!   clearance (`thread_needle.rs`), before the tools and the tissue and after them;
//! - **contacts** then put each node back outside the tissue (last, so a thread pinched between a tool and the
//!   skin stays out of the skin, but for the self pass after them):
//!   - continuous: a node whose path this substep entered a surface (`collision::crossing_nearest`, the
//!     triangles as they are now) takes the point it crossed as its contact, and goes back out however far
//!     past it it went;
//!   - resting: a node with a contact is kept at least the thread's radius out along that triangle's normal
//!     now (a surface that moves up under a resting thread lifts it), with Coulomb friction on the substep's
//!     motion along the surface (position-based: the sliding is cut by `mu` times the depth put back), and
//!     its contact follows it across the surface (the surface point under it); it lets go when the node lifts
//!     off or slides off the triangle's neighbourhood;
//!   - the side: a node between two of its holes in an object (by their parity, `inside_by_holes`) is kept
//!     *inside* that object the same way, the normal turned; a node within 2 mm of a hole, on the surface and
//!     along the thread, may cross any surface.
//!
//! One-way: the tissue holds the thread out, the thread's weight (a hundredth of a gram) does not press the
//! tissue. Known gaps, in `docs/suturing.md`: a surface that sweeps over a node not resting on it is not seen;
//! a tool faster than about a millimetre a tick can carry a node through itself; a segment through a sheet
//! thinner than itself is not put back.
//!
//! Must not: allocate once built, or panic on any input (a non-finite tail leaves the thread as it was).

use nalgebra::UnitQuaternion;

mod holds;
mod lay;
mod tear;

use super::thread_edge_contact::keep_segment_out;
use super::thread_grip::{MAX_GRIPS, ThreadGrip};
use super::thread_hole::{ThreadHole, inside_by_holes, take_nodes};
use super::thread_needle::{NeedleWire, WireSegment};
use super::thread_self_contact::SelfContact;
use super::thread_tool_contact::keep_segments_out_of_tools;
use super::thread_track::{MAX_TRACK_RINGS, refresh_tracks};
use super::{MAX_HOLES, SurfacePoint, ThreadChain};
use crate::collision::{SurfaceCollider, ToolCollider, crossing_nearest};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// Standard gravity, mm/s^2 (the thread's weight when the world's gravity is off: worlds are z up).
pub const STANDARD_GRAVITY_MM_PER_S2: f32 = 9810.0;
/// The thread's diameter, mm (a 3-0 suture is 0.20-0.25 mm).
pub const THREAD_DIAMETER_MM: f32 = 0.25;
/// Mass per length, kg/mm (nylon 3-0 is about 0.06 g/m, braided silk about 0.1).
const LINEAR_DENSITY_KG_PER_MM: f32 = 1.0e-7;
/// Axial rigidity EA, N: 5 N stretches it 0.5% (the acceptance allows 1%; real nylon stretches more, but a
/// suture that visibly stretches reads as rubber).
const AXIAL_RIGIDITY_N: f32 = 1000.0;
/// Flexural rigidity EI, N mm^2: nylon (E about 3 GPa) 0.25 mm thick is 0.58.
const BEND_RIGIDITY_N_MM2: f32 = 0.5;
/// Air and wetness drag on every node, 1/s.
const DRAG_PER_S: f32 = 5.0;
/// Substeps of the thread per tick, and the most Newton steps of its length solve per substep (it stops once
/// converged: `thread_solve.rs`).
const SUBSTEPS: usize = 4;
const NEWTON: usize = 8;
/// Most self passes after the contacts in a substep (each is Gauss-Seidel: a pair put apart may press its
/// neighbour; they stop once none is pushed).
const SELF_PASSES_AFTER: usize = 3;
/// Thread-tissue Coulomb coefficient (wet suture on skin).
const SURFACE_FRICTION: f32 = 0.3;
/// A resting node this far off its contact's plane beyond the radius has lifted off it, mm.
const LIFT_MM: f32 = 0.5;
/// A node this far across the surface from its contact point looks for the point under it, mm.
const FOLLOW_MM: f32 = 0.3;
/// A node this far across the surface from its contact point, with no surface under it, lets it go, mm.
const SLID_OFF_MM: f32 = 2.0;
/// A crossing this close to one of the thread's holes is the thread running through it, mm.
const HOLE_CLEARANCE_MM: f32 = 2.0;
/// Nodes this close (in nodes) to one a grip holds are not pushed by the gripping tool's body.
const GRIP_CLEAR_NODES: usize = 2;
/// The tree's query box is loosened by this much for a node's path, mm.
const CROSSING_MARGIN_MM: f32 = 0.5;

/// A thread's size (the world's keys `thread_length_mm`, `thread_segments`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThreadSpec {
    /// Length, mm (0: no thread).
    pub length_mm: f32,
    /// Segments (each at most 2.5 mm long).
    pub segments: u16,
}

impl ThreadSpec {
    /// 150 mm in 64 segments of 2.34 mm (iMSTK uses 64 of about 2.3).
    pub const DEFAULT: ThreadSpec = ThreadSpec {
        length_mm: 150.0,
        segments: 64,
    };
    /// No thread.
    pub const NONE: ThreadSpec = ThreadSpec {
        length_mm: 0.0,
        segments: 0,
    };
    /// The longest segment allowed, mm.
    pub const MAX_SEGMENT_MM: f32 = 2.5;

    /// Each segment's rest length, mm.
    pub fn segment_mm(&self) -> f32 {
        self.length_mm / f32::from(self.segments.max(1))
    }

    /// A thread at all.
    pub fn is_some(&self) -> bool {
        self.segments > 0 && self.length_mm > 0.0
    }
}

/// The object `o` a thread meets: its collider, model and state (None: not met).
pub type ThreadObject<'a> = (&'a SurfaceCollider, &'a MassSpringModel, &'a TissueState);

/// A tool part a thread meets: its collider and its pose this tick (origin, mm, and rotation).
pub type ThreadTool<'a> = (&'a ToolCollider, Vec3, UnitQuaternion<f32>);

/// A thread on a needle's tail (module doc).
#[derive(Debug, Clone)]
pub struct SutureThread {
    chain: ThreadChain,
    /// Per node, the surface point it rests on.
    contacts: Vec<Option<SurfacePoint>>,
    /// Per node, whether its contact keeps it inside its object (the side it was made on).
    contact_inside: Vec<bool>,
    segment_mm: f32,
    gravity_mm_per_s2: Vec3,
    /// The tail last tick (None: not laid out yet, or to be laid out again).
    last_tail_mm: Option<Vec3>,
    /// Pairs of segments held apart last tick.
    pairs_apart: u32,
    /// Its contact with itself (`thread_self_contact.rs`).
    self_contact: SelfContact,
    /// The holes the thread runs through, in the order it entered them.
    holes: Vec<ThreadHole>,
    /// The rings of the needle's tracks inside the tissue it runs through, in the order it entered them.
    tracks: Vec<ThreadHole>,
    /// The jaws holding it (`thread_grip.rs`).
    grips: Vec<ThreadGrip>,
    /// Per node, whether a hole or a ring holds it (scratch, kept up through a tick).
    claimed: Vec<bool>,
    /// Per node, its material coordinate (scratch: the chain's, for the contacts inside its step), mm.
    node_u_mm: Vec<f32>,
    /// Per node, the unit normal of the surface it rests on (zero: none), from its last contact pass: the self
    /// contact does not push a node into the surface under it (`thread_self_contact.rs`).
    floor: Vec<Vec3>,
}

impl SutureThread {
    /// A thread of `spec`, under `gravity_mm_per_s2` (zero: standard gravity down -z), not yet laid out. None
    /// for no thread or one whose segments are longer than [`ThreadSpec::MAX_SEGMENT_MM`] (the loader refuses
    /// those first).
    pub fn new(spec: ThreadSpec, gravity_mm_per_s2: Vec3) -> Option<Self> {
        let segment_mm = spec.segment_mm();
        if !spec.is_some() || segment_mm.is_nan() || segment_mm > ThreadSpec::MAX_SEGMENT_MM {
            return None;
        }
        let nodes: Vec<Vec3> = (0..=spec.segments)
            .map(|i| Vec3::new(-segment_mm * f32::from(i), 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(
            &nodes,
            LINEAR_DENSITY_KG_PER_MM * segment_mm,
            AXIAL_RIGIDITY_N,
            DRAG_PER_S,
        )?;
        chain.set_held(0, true, 0.0);
        chain.set_bending(BEND_RIGIDITY_N_MM2);
        let gravity_mm_per_s2 = if gravity_mm_per_s2 == Vec3::zeros() {
            Vec3::new(0.0, 0.0, -STANDARD_GRAVITY_MM_PER_S2)
        } else {
            gravity_mm_per_s2
        };
        Some(Self {
            contacts: vec![None; nodes.len()],
            contact_inside: vec![false; nodes.len()],
            chain,
            segment_mm,
            gravity_mm_per_s2,
            last_tail_mm: None,
            pairs_apart: 0,
            self_contact: SelfContact::new(usize::from(spec.segments)),
            holes: Vec::with_capacity(MAX_HOLES),
            tracks: Vec::with_capacity(MAX_TRACK_RINGS),
            grips: Vec::with_capacity(MAX_GRIPS),
            claimed: vec![false; nodes.len()],
            node_u_mm: vec![0.0; nodes.len()],
            floor: vec![Vec3::zeros(); nodes.len()],
        })
    }

    /// The nodes, tail first, mm.
    pub fn nodes_mm(&self) -> &[Vec3] {
        &self.chain.positions_mm
    }

    /// The chain (tensions, length).
    pub fn chain(&self) -> &ThreadChain {
        &self.chain
    }

    /// Nodes resting on a surface now.
    pub fn resting_nodes(&self) -> usize {
        self.contacts.iter().filter(|c| c.is_some()).count()
    }

    /// The thread's pull on the needle's tail, world, N (the first segment's tension along it).
    pub fn pull_on_tail_n(&self) -> Vec3 {
        pull_on_node_n(&self.chain, 0)
    }

    /// A node's mass, kg.
    fn node_mass_kg(&self) -> f32 {
        LINEAR_DENSITY_KG_PER_MM * self.segment_mm
    }

    /// Up, for the thread: against its gravity (unit).
    pub fn up_unit(&self) -> Vec3 {
        -self
            .gravity_mm_per_s2
            .try_normalize(1e-6)
            .unwrap_or(Vec3::new(0.0, 0.0, -1.0))
    }

    /// One tick of `dt_s` with the tail at `tail_mm` (from last tick's, on a straight line), against the
    /// tool parts `tool(0..tools)` and its own `needle`'s wire at their poses this tick, and then the surfaces
    /// of `objects` objects (`object(o)`). A thread not laid out, or a non-finite tail, does nothing. No allocation.
    #[allow(clippy::too_many_arguments)] // the tail, and what the thread meets: tools and objects
    pub fn step<'a, 'b>(
        &mut self,
        dt_s: f32,
        tail_mm: &Vec3,
        tools: usize,
        tool: impl Fn(usize) -> Option<ThreadTool<'b>>,
        needle: Option<&NeedleWire>,
        objects: usize,
        object: impl Fn(usize) -> Option<ThreadObject<'a>>,
    ) {
        let Some(from_tail) = self.last_tail_mm else {
            return;
        };
        if !(dt_s > 0.0 && tail_mm.iter().all(|c| c.is_finite())) {
            return;
        }
        let h_s = dt_s / SUBSTEPS as f32;
        // Where the holes and the tracks hold it this tick; one whose tissue is gone lets go.
        let placed = |hole: &mut ThreadHole| {
            object(usize::from(hole.point.object()))
                .is_some_and(|(_, model, state)| hole.place(model, state))
        };
        self.holes.retain_mut(placed);
        self.tracks.retain_mut(placed);
        refresh_tracks(&self.holes, &mut self.tracks, &self.chain, objects, &object);
        // Each hole and ring holds a node of its own: the holes first.
        take_nodes(
            &mut self.holes,
            &mut self.tracks,
            &mut self.chain,
            &mut self.claimed,
        );
        // Where the jaws hold it this tick; a released tool lets go.
        self.keep_grips(|grip, _| {
            tool(2 * usize::from(grip.tool))
                .is_some_and(|(_, position_mm, rotation)| grip.aim(&position_mm, &rotation))
        });
        let contacts = &mut self.contacts;
        let contact_inside = &mut self.contact_inside;
        let self_contact = &mut self.self_contact;
        let holes = &mut self.holes;
        let tracks = &mut self.tracks;
        let grips = &self.grips;
        let segment_mm = self.segment_mm;
        let claimed = &mut self.claimed;
        let node_u_mm = &mut self.node_u_mm;
        let floor = &mut self.floor;
        let mut pairs_apart = 0;
        for k in 1..=SUBSTEPS {
            let s = k as f32 / SUBSTEPS as f32;
            self.chain.positions_mm[0] = from_tail + (tail_mm - from_tail) * s;
            // The holes hold their nodes inside the length solve (thread_hole.rs).
            for hole in holes.iter().chain(tracks.iter()) {
                if let Some((i, hold)) = hole.node_hold() {
                    self.chain.hold_node(i, hold);
                }
                if let Some((i, slide)) = hole.node_slide(&self.chain, h_s) {
                    self.chain.slide_node(i, slide);
                }
            }
            node_u_mm.copy_from_slice(self.chain.node_u_mm());
            // The nodes a hole or a ring holds (kept up by `take_nodes` and each hand-across): each is the
            // hole's, and the contacts leave it alone.
            let by_hole: &[bool] = claimed;
            // The jaws carry theirs.
            for grip in grips {
                if let Some(p) = self.chain.positions_mm.get_mut(grip.node as usize) {
                    *p = grip.place_at(s);
                }
            }
            self.chain
                .step_with(h_s, &self.gravity_mm_per_s2, NEWTON, |before, now, w| {
                    // Each segment against the tissue's edges (`thread_edge_contact.rs`): not one a hole holds
                    // a node of, nor one beside a hole or inside an object it runs through. Before the nodes'
                    // contacts and after them: a node put clear of a tool or a face may draw its segment back
                    // across an edge, and one pushed off an edge may meet a tool.
                    let edge_pass = |now: &mut [Vec3]| {
                        for i in 0..now.len().saturating_sub(1) {
                            if w[i] + w[i + 1] <= 0.0 || by_hole[i] || by_hole[i + 1] {
                                continue;
                            }
                            let (u0, u1) = (node_u_mm[i], node_u_mm[i + 1]);
                            for o in 0..objects {
                                let near_hole = holes.iter().any(|h| {
                                    usize::from(h.point.object()) == o
                                        && (h.u_mm - u0).abs().min((h.u_mm - u1).abs())
                                            < HOLE_CLEARANCE_MM + segment_mm
                                });
                                if near_hole
                                    || inside_by_holes(holes, o as u16, u0)
                                    || inside_by_holes(holes, o as u16, u1)
                                {
                                    continue;
                                }
                                let Some((collider, model, state)) = object(o) else {
                                    continue;
                                };
                                let (head, rest) = now.split_at_mut(i + 1);
                                keep_segment_out(
                                    &mut head[i],
                                    &mut rest[0],
                                    w[i],
                                    w[i + 1],
                                    collider,
                                    model.triangles(),
                                    &state.positions_mm,
                                    0.5 * THREAD_DIAMETER_MM,
                                );
                            }
                        }
                    };
                    // Each segment against its own needle's wire (`thread_needle.rs`), the first swaged to it;
                    // a node a hole holds is the hole's.
                    let needle_pass = |now: &mut [Vec3], floor: &[Vec3]| {
                        let Some(needle) = needle else {
                            return;
                        };
                        let weight = |i: usize| {
                            if by_hole[i] { 0.0 } else { w[i] }
                        };
                        for i in 0..now.len().saturating_sub(1) {
                            let segment = WireSegment {
                                now: [now[i], now[i + 1]],
                                before: [before[i], before[i + 1]],
                                weights: [weight(i), weight(i + 1)],
                                floors: [floor[i], floor[i + 1]],
                                swaged: i == 0,
                            };
                            if let Some([a, b]) =
                                needle.clear_segment(&segment, 0.5 * THREAD_DIAMETER_MM)
                            {
                                (now[i], now[i + 1]) = (a, b);
                            }
                        }
                    };
                    // Each segment against the tool parts (`thread_tool_contact.rs`): a segment, not only its
                    // nodes, is kept out of a tool (not the one whose jaws hold a node of it or beside it).
                    let tool_pass = |now: &mut [Vec3], floor: &[Vec3]| {
                        keep_segments_out_of_tools(
                            now,
                            before,
                            |i| if by_hole[i] { 0.0 } else { w[i] },
                            floor,
                            |i| jaws_beside(grips, i),
                            tools,
                            &tool,
                        );
                    };
                    let mut contact_pass = |now: &mut [Vec3], floor: &mut [Vec3]| {
                        edge_pass(now);
                        needle_pass(now, floor);
                        for i in 0..now.len() {
                            if w[i] > 0.0 {
                                // A node a hole holds is the hole's: a tool in the same hole (the needle, the
                                // jaws following it through) does not push it out of it.
                                if !by_hole[i] {
                                    // The thread runs out between the jaws holding it: their
                                    // body does not push the nodes beside the one they hold.
                                    let jaws = jaws_beside(grips, i);
                                    keep_clear_of_tools(&mut now[i], tools, &tool, jaws, None);
                                }
                                // Kept inside an object it runs through (between its holes there), and free to
                                // cross a surface beside one of its holes.
                                let u_mm = node_u_mm[i];
                                // Beside a hole: near it both on the surface and along the thread (a
                                // stretch of thread further on that lies near it is kept out as any).
                                let exempt = |o: usize, at: &Vec3| {
                                    holes.iter().any(|h| {
                                        usize::from(h.point.object()) == o
                                            && (h.u_mm - u_mm).abs()
                                                < HOLE_CLEARANCE_MM + segment_mm
                                            && (h.place_mm() - at).norm() < HOLE_CLEARANCE_MM
                                    })
                                };
                                let inside = |o: usize| inside_by_holes(holes, o as u16, u_mm);
                                let side = keep_to_side(
                                    &before[i],
                                    &mut now[i],
                                    &mut contacts[i],
                                    &mut contact_inside[i],
                                    objects,
                                    &object,
                                    &inside,
                                    &exempt,
                                );
                                // Pinched between a tool and the surface it rests on: the surface put it back
                                // into the tool, so the tool now pushes it along the surface, out from under.
                                floor[i] = side.resting_on.unwrap_or_else(Vec3::zeros);
                                if let Some(normal) = side.resting_on.filter(|_| side.pushed)
                                    && !by_hole[i]
                                {
                                    let jaws = jaws_beside(grips, i);
                                    keep_clear_of_tools(
                                        &mut now[i],
                                        tools,
                                        &tool,
                                        jaws,
                                        Some(&normal),
                                    );
                                }
                            }
                        }
                        tool_pass(now, floor);
                        needle_pass(now, floor);
                        edge_pass(now);
                    };
                    // Itself, then the tools and the tissue, then itself once more: a contact may have pushed a
                    // node through a segment beside it. (A second contact pass after that kept every node out of
                    // the skin and tools but let more pairs through: docs/suturing.md, "Robust over seeds".)
                    pairs_apart +=
                        self_contact.keep_apart(before, now, w, floor, THREAD_DIAMETER_MM);
                    contact_pass(now, floor);
                    for _ in 0..SELF_PASSES_AFTER {
                        let pushed =
                            self_contact.keep_apart(before, now, w, floor, THREAD_DIAMETER_MM);
                        pairs_apart += pushed;
                        if pushed == 0 {
                            break;
                        }
                    }
                });
            // Then the thread slides through them.
            for hole in holes.iter_mut().chain(tracks.iter_mut()) {
                hole.after_substep(&mut self.chain, claimed, h_s);
            }
        }
        // The pull on each jaw; a thread pulled harder than the jaws hold slips out of them.
        self.keep_grips(|grip, chain| grip.after_step(pull_on_node_n(chain, grip.node as usize)));
        self.last_tail_mm = Some(*tail_mm);
        self.pairs_apart = pairs_apart;
    }

    /// Pairs of its segments held apart in the last tick (summed over its substeps).
    pub fn pairs_held_apart(&self) -> u32 {
        self.pairs_apart
    }
}

/// The tool whose jaws hold a node within [`GRIP_CLEAR_NODES`] of node `i`: its body does not push node `i`
/// (the thread runs out between the jaws).
fn jaws_beside(grips: &[ThreadGrip], i: usize) -> Option<usize> {
    grips
        .iter()
        .find(|g| (g.node as usize).abs_diff(i) <= GRIP_CLEAR_NODES)
        .map(|g| usize::from(g.tool))
}

/// The thread's pull on node `i` (held: the tail, a grip), world, N: the segments either side pull it along
/// them with their tension (a slack or compressed one pulls nothing, nor one whose tension is not finite).
fn pull_on_node_n(chain: &ThreadChain, i: usize) -> Vec3 {
    let p = &chain.positions_mm;
    let tension = chain.tension_n();
    let mut pull = Vec3::zeros();
    let Some(&at) = p.get(i) else {
        return pull;
    };
    for (segment, neighbour) in [(i.wrapping_sub(1), i.wrapping_sub(1)), (i, i + 1)] {
        let (Some(&t), Some(q)) = (tension.get(segment), p.get(neighbour)) else {
            continue;
        };
        if !t.is_finite() {
            continue;
        }
        if let Some(along) = (q - at).try_normalize(1e-9) {
            pull += along * t.max(0.0);
        }
    }
    pull
}

/// A surface point's place and the outward unit normal of its triangle as the surface is now.
fn place_and_normal(
    point: &SurfacePoint,
    model: &MassSpringModel,
    state: &TissueState,
) -> Option<(Vec3, Vec3)> {
    let [a, b, c] = point
        .corners(model)?
        .map(|i| state.positions_mm.get(i as usize).copied());
    let (a, b, c) = (a?, b?, c?);
    let normal = (b - a).cross(&(c - a)).try_normalize(1e-12)?;
    let w = point.barycentric;
    Some((a * w[0] + b * w[1] + c * w[2], normal))
}

/// Put one node out of the tool parts, the thread's radius clear of each (nearest way out, no friction).
/// With `along_surface` (the unit normal of a surface the node rests on), the way out is kept in that
/// surface's plane: the nearest way out's part along the plane, lengthened so it clears the tool as far as
/// the nearest way would (a locally flat tool), and nothing when the tool presses straight into the surface
/// (within about 8 degrees of its normal: the tool is in the tissue, and the tissue's side wins).
fn keep_clear_of_tools<'b>(
    now: &mut Vec3,
    tools: usize,
    tool: &impl Fn(usize) -> Option<ThreadTool<'b>>,
    skip_tool: Option<usize>,
    along_surface: Option<&Vec3>,
) {
    let radius_mm = 0.5 * THREAD_DIAMETER_MM;
    for k in (0..tools).filter(|k| skip_tool != Some(k / 2)) {
        let Some((collider, position_mm, rotation)) = tool(k) else {
            continue;
        };
        let near = collider.aabb(&position_mm, &rotation, radius_mm);
        if !near.contains_local_point(crate::collision::glam_boundary::to_parry(now)) {
            continue;
        }
        let Some(to) = collider.keep_clear(&position_mm, &rotation, now, radius_mm) else {
            continue;
        };
        let Some(normal) = along_surface else {
            *now = to;
            continue;
        };
        let out = to - *now;
        let along = out - normal * out.dot(normal);
        // The nearest way out's share along the plane: out . along / (|out| |along|) = |along| / |out|.
        let share = along.norm() / out.norm().max(1e-12);
        if share > 0.14 {
            *now += along * (1.0 / (share * share));
        }
    }
}

/// What [`keep_to_side`] did with a node.
#[derive(Debug, Clone, Copy, Default)]
struct KeptToSide {
    /// The unit normal (toward the node's side) of the surface it rests on, if it has a contact.
    resting_on: Option<Vec3>,
    /// Whether that surface pushed it back this time.
    pushed: bool,
}

/// Put one node, which moved from `before` to `now` this substep, back outside the surfaces (module doc).
#[allow(clippy::too_many_arguments)] // the node's motion and contact, the objects, and which side of each
fn keep_to_side<'a>(
    before: &Vec3,
    now: &mut Vec3,
    contact: &mut Option<SurfacePoint>,
    contact_inside: &mut bool,
    objects: usize,
    object: &impl Fn(usize) -> Option<ThreadObject<'a>>,
    inside: &impl Fn(usize) -> bool,
    exempt: &impl Fn(usize, &Vec3) -> bool,
) -> KeptToSide {
    let radius_mm = 0.5 * THREAD_DIAMETER_MM;
    // A contact made on the other side of its surface is void: the thread has since run through one of its
    // holes there, and the node is to cross that surface by the hole, not be thrown through it.
    if contact.is_some_and(|c| inside(usize::from(c.object)) != *contact_inside) {
        *contact = None;
    }
    // Continuous: the first surface its path crossed the wrong way (into an object it is outside of, out of
    // one it runs inside).
    let mut first: Option<(usize, crate::collision::SurfaceCrossing)> = None;
    for o in 0..objects {
        let Some((collider, model, state)) = object(o) else {
            continue;
        };
        if let Some(hit) = crossing_nearest(
            collider,
            model.triangles(),
            &state.positions_mm,
            before,
            now,
            CROSSING_MARGIN_MM,
            0.0,
            Some(!inside(o)),
        ) && first.is_none_or(|(_, f)| hit.along < f.along)
            && !exempt(o, &hit.point_mm)
        {
            first = Some((o, hit));
        }
    }
    let entered = first.is_some();
    if let Some((o, hit)) = first {
        *contact = Some(SurfacePoint {
            object: o as u16,
            triangle: hit.triangle,
            barycentric: hit.barycentric,
        });
        *contact_inside = inside(o);
    }
    let Some(point) = *contact else {
        return KeptToSide::default();
    };
    let Some((collider, model, state)) = object(usize::from(point.object))
        .filter(|_| entered || !exempt(usize::from(point.object), now))
    else {
        *contact = None;
        return KeptToSide::default();
    };
    let Some((place, outward)) = place_and_normal(&point, model, state) else {
        *contact = None;
        return KeptToSide::default();
    };
    // The normal toward the side it belongs on.
    let normal = if inside(usize::from(point.object)) {
        -outward
    } else {
        outward
    };
    let depth = (*now - place).dot(&normal);
    let across = (*now - place) - normal * depth;
    // A node that entered this substep goes back out however far it went (a fast one may be millimetres past
    // the point it crossed); a resting one may have lifted off or slid past the triangle's edge.
    if !entered && (depth > radius_mm + LIFT_MM || across.norm() > SLID_OFF_MM) {
        *contact = None;
        return KeptToSide::default();
    }
    let pushed = depth < radius_mm;
    if pushed {
        let put_back = radius_mm - depth;
        *now += normal * put_back;
        // Coulomb, position-based: the substep's sliding is cut by mu times the depth put back.
        let moved = *now - before;
        let sliding = moved - normal * moved.dot(&normal);
        let slide = sliding.norm();
        let limit = SURFACE_FRICTION * put_back;
        if slide > 0.0 {
            *now -= sliding * (limit / slide).min(1.0);
        }
    }
    // Follow across the surface: the point under the node now.
    if across.norm() > FOLLOW_MM {
        let reach = normal * (radius_mm + LIFT_MM + 1.0);
        if let Some(under) = crossing_nearest(
            collider,
            model.triangles(),
            &state.positions_mm,
            &(*now + reach),
            &(*now - reach),
            CROSSING_MARGIN_MM,
            0.5,
            Some(!inside(usize::from(point.object))),
        ) {
            *contact = Some(SurfacePoint {
                object: point.object,
                triangle: under.triangle,
                barycentric: under.barycentric,
            });
        }
    }
    KeptToSide {
        resting_on: Some(normal),
        pushed,
    }
}

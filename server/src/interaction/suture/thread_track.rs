//! The needle's track inside the tissue: the rings that hold the thread between its holes.
//!
//! Owns: the tick's track stage ([`refresh_tracks`]): when a ring is laid ([`lay_tracks`]) and dropped
//! ([`drop_rings_beside_holes`]). A ring is a [`ThreadHole`] on a material point of the volume
//! ([`HolePoint::Volume`], `volume_point.rs`): it holds the thread as a hole does and does not change its side.
//!
//! Why: a thread held only at the two holes of a bite runs straight between them, and drawn tight it lifted the
//! holes on a wound's faces from 7.3 mm deep to 1.9 mm, as a sling cuts up through what it holds
//! (`docs/suturing.md`, "Next, in detail"). While the needle's tail runs inside an object, the tissue where it
//! is takes the thread every [`TRACK_SPACING_MM`] of the path.
//!
//! Must not: allocate (rings are capped at [`MAX_TRACK_RINGS`]) or panic.

use super::ThreadChain;
use super::thread::ThreadObject;
use super::thread_hole::{HolePoint, ThreadHole, inside_by_holes};
use super::volume_point::VolumePoint;
use crate::tissue::Vec3;

/// A ring every this far along the track, mm (two segments: each ring holds a node of its own, and a node
/// between two keeps the thread free to bend between them).
pub const TRACK_SPACING_MM: f32 = 5.0;
/// The most track rings a thread runs through.
pub const MAX_TRACK_RINGS: usize = 64;

/// The tick's track stage, before the holes and rings take their nodes: the rings beside a hole dropped
/// ([`drop_rings_beside_holes`]), then a ring laid on the chain's node behind the needle's tail, where it is,
/// if the track has reached the next ring's place ([`lay_tracks`]).
pub fn refresh_tracks<'a>(
    holes: &[ThreadHole],
    tracks: &mut Vec<ThreadHole>,
    chain: &ThreadChain,
    objects: usize,
    object: &impl Fn(usize) -> Option<ThreadObject<'a>>,
) {
    drop_rings_beside_holes(holes, tracks);
    if let (Some(node_mm), Some(&node_u_mm)) = (chain.positions_mm.get(1), chain.node_u_mm().get(1))
    {
        lay_tracks(holes, tracks, node_mm, node_u_mm, objects, object);
    }
}

/// Where the thread's first free node (`node_mm`, `node_u_mm` along the thread from the tail: the one behind
/// the needle's tail, which the tail drew along its track) runs inside an object (by the `holes`' parity) and
/// lies [`TRACK_SPACING_MM`] along the thread from the last hole or ring there, the tissue there takes the
/// thread in a ring with the latest hole's friction, squeeze and stiffness, pushed on `tracks`.
///
/// The ring is laid on that node, where it is, and not at the tail: the tail's node is the needle's, so a
/// ring at the tail took the next node and set it a hair from the tail, a segment back along the thread in a
/// tick, and the length solve answered with a jolt on the tail (3.6-4.7 N for a tick, then 0-1.9 N chatter
/// for 100 ms, where 0.2 N was being drawn).
pub fn lay_tracks<'a>(
    holes: &[ThreadHole],
    tracks: &mut Vec<ThreadHole>,
    node_mm: &Vec3,
    node_u_mm: f32,
    objects: usize,
    object: &impl Fn(usize) -> Option<ThreadObject<'a>>,
) {
    for o in 0..objects {
        let id = o as u16;
        if tracks.len() >= MAX_TRACK_RINGS || !inside_by_holes(holes, id, node_u_mm) {
            continue;
        }
        let nearest = holes
            .iter()
            .chain(tracks.iter())
            .filter(|h| h.point.object() == id)
            .map(|h| h.u_mm)
            .fold(f32::INFINITY, f32::min);
        let Some(entry) = holes.iter().rev().find(|h| h.point.object() == id) else {
            continue;
        };
        if nearest - node_u_mm < TRACK_SPACING_MM {
            continue;
        }
        let Some((_, model, state)) = object(o) else {
            continue;
        };
        let Some(point) = VolumePoint::locate(id, model, state, node_mm) else {
            continue;
        };
        let mut ring = ThreadHole::new(
            HolePoint::Volume(point),
            node_u_mm,
            entry.squeeze_n,
            entry.friction,
            entry.stiffness_n_per_mm,
        );
        if ring.place(model, state) {
            tracks.push(ring);
        }
    }
}

/// A ring beside a hole of its object along the thread is the hole's: one laid as the tail reached the way out,
/// before the needle had left that hole and handed it over, is dropped. (Along the thread, not in space: a stitch
/// drawn tight brings its rings near its holes.)
pub fn drop_rings_beside_holes(holes: &[ThreadHole], tracks: &mut Vec<ThreadHole>) {
    tracks.retain(|r| {
        !holes.iter().any(|h| {
            h.point.object() == r.point.object() && (h.u_mm - r.u_mm).abs() < 0.5 * TRACK_SPACING_MM
        })
    });
}

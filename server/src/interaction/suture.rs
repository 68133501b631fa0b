//! Suturing: a curved needle, its path through tissue, the thread and the stitches (issue 32).
//!
//! Owns, so far:
//! - the needle's rigid geometry ([`NeedleArc`]: the arc in the needle's own frame, its tip and tangent, how
//!   far a point lies off the arc's path);
//! - the needle driver and where the needle sits in its jaws ([`NeedleDriverSpec`]);
//! - who holds the needle ([`NeedleHold`]: its driver's jaws, a grasper's after a hand-off, or nothing, the
//!   needle then held in the tissue by its holes);
//! - a sharp tip pressing a surface ([`TipContact`], on a [`SurfacePoint`]: the surface tents under it);
//! - the needle against the tissue ([`NeedleTissue`]: tenting, puncture on force and angle, the holes it
//!   passes through; a material's [`PunctureSpec`]);
//! - the path constraint: each [`Hole`] holds the needle on its path, and it slides through with friction;
//! - the thread's chain held to length by a direct solve ([`ThreadChain`]), with soft bending;
//! - the thread on the needle's tail ([`SutureThread`]): it follows the needle, hangs and lies on the tissue
//!   and against the tools without passing into them, and keeps off itself (`thread_self_contact`).
//! - a suture cutting out of its tissue ([`plan_hole_tear`]): a hole pulled past the material's limit tears
//!   the tissue toward the pull, and the thread cuts through a bite's edge.
//!
//! The rest of the thread and the stitches come next, each in its own file here, behind the tick's
//! instrument extension point (`sim/instrument.rs`; the needle driver is `sim/instruments/needle_driver.rs`);
//! `docs/suturing.md` is the design.
//!
//! Must not: hold tick state beyond what each type owns, or allocate in a tick without a topology change.

mod hole;
mod hole_point;
mod hole_tear;
mod knot;
mod needle;
mod needle_arc;
mod needle_fall;
mod needle_hold;
mod puncture;
mod thread;
mod thread_chain;
mod thread_edge_contact;
mod thread_grip;
mod thread_hole;
mod thread_needle;
pub mod thread_self_contact;
mod thread_solve;
mod thread_tool_contact;
mod thread_track;
mod tip_contact;
mod volume_point;

pub use crate::tissue::PunctureSpec;
pub use hole::Hole;
pub use hole_tear::{HoleTear, TEAR_PERIOD_S, plan_hole_tear, surface_point_near};
pub use knot::{KnotKind, KnotReader, Throws};
pub use needle::NeedleDriverSpec;
pub use needle_arc::{ArcPoint, NeedleArc, NeedleArcError, PathOffset};
pub use needle_fall::NeedleFall;
pub use needle_hold::{NeedleHold, NeedleHolder};
pub use puncture::{MAX_HOLES, NeedleEvents, NeedleTissue, PopPreview, TipPhase};
pub use thread::{
    STANDARD_GRAVITY_MM_PER_S2, SutureThread, THREAD_DIAMETER_MM, ThreadObject, ThreadSpec,
    ThreadTool,
};
pub use thread_chain::{NodeHold, ThreadChain};
pub use thread_grip::{GRIP_SLIP_N, MAX_GRIPS, ThreadGrip};
pub use thread_hole::{HolePoint, ThreadHole, inside_by_holes};
pub use thread_needle::{NeedleWire, WireSegment};
pub use thread_solve::NodeSlide;
pub use tip_contact::{SurfacePoint, TipContact};
pub use volume_point::VolumePoint;

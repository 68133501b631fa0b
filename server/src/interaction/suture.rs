//! Suturing: a curved needle, its path through tissue, the thread and the stitches (issue 32).
//!
//! Owns, so far: the needle's rigid geometry ([`NeedleArc`]: the arc in the needle's frame, its tip and
//! tangent, the nearest point on it to any point, and how far a point lies off the arc's path). The needle's
//! puncture, its anchors along the path, the thread and the stitches come next, each in its own file here,
//! behind the tick's instrument extension point (`sim/instrument.rs`); `docs/suturing.md` is the design.
//!
//! Must not: move tissue or hold tick state (geometry here is pure and allocation-free).

mod needle_arc;

pub use needle_arc::{ArcPoint, NeedleArc, NeedleArcError, PathOffset};

//! How far a wound between two sim objects is open (`crate::tissue::wound_gap`): the metric a stitch is judged
//! by ("wound gap after tightening").
//!
//! Owns: [`wound_gap_mm`]. Must not: allocate or panic.

use crate::sim::SimObject;
pub use crate::tissue::wound_gap::wound_gap_between_mm;

/// The gap of the wound between objects `a` and `b`, mm (module doc); `None` for an object without nodes or
/// two objects whose rest boxes have the same centre.
pub fn wound_gap_mm(a: &SimObject, b: &SimObject) -> Option<f32> {
    wound_gap_between_mm(
        (a.model.rest_positions_mm(), &a.state.positions_mm),
        (b.model.rest_positions_mm(), &b.state.positions_mm),
    )
}

//! The knot a suture exercise read, as its score reports it.
//!
//! Owns: [`KnotScore`] and [`secure_knot`] (which throws tie a stitch off). The exercise
//! (`exercise.rs`) reads the knot each tick and fills the score.

use serde::{Deserialize, Serialize};

/// The knot a suture exercise read.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct KnotScore {
    /// What a surgeon calls the knot read at the end (`square knot`, `half knot`, ...; None: no knot).
    pub name: Option<String>,
    /// Its throws: single and double, right- and left-handed.
    pub throws: [u8; 4],
    /// Secure: two throws or more that can alternate hands.
    pub secure: bool,
    /// Knots read that came undone.
    pub undone: u32,
}

/// Whether `throws` make a secure knot: two or more, alternating hands where they can (a square knot, a
/// surgeon's knot, three throws right-left-right; not a half knot, a surgeon's throw alone or a granny).
pub fn secure_knot(throws: &crate::interaction::suture::Throws) -> bool {
    throws.count() >= 2 && throws.can_alternate()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interaction::suture::Throws;

    #[test]
    fn square_and_surgeons_knots_are_secure_half_knots_and_grannies_are_not() {
        let knot = |single_right, single_left, double_right, double_left| Throws {
            single_right,
            single_left,
            double_right,
            double_left,
        };
        assert!(secure_knot(&knot(1, 1, 0, 0)));
        assert!(secure_knot(&knot(0, 1, 1, 0)));
        assert!(secure_knot(&knot(2, 1, 0, 0)));
        assert!(!secure_knot(&knot(1, 0, 0, 0)));
        assert!(!secure_knot(&knot(0, 0, 1, 0)));
        assert!(!secure_knot(&knot(2, 0, 0, 0)));
        assert!(!secure_knot(&Throws::default()));
    }
}

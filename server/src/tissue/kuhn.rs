//! Kuhn's subdivision of a cube into six tetrahedra around its main diagonal (conforming across faces): the
//! table structured tetrahedral blocks and the element tests are built from.
//!
//! Owns: [`KUHN`].

/// The six tetrahedra of a cube whose corners are numbered by their bits (x = 1, y = 2, z = 4), all around
/// the diagonal from corner 0 to corner 7.
pub const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 3, 2, 7],
    [0, 2, 6, 7],
    [0, 6, 4, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
];

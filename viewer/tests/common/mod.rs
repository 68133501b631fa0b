//! Test fixtures shared by the viewer's integration tests: a grid sheet like the pad, and one tool.
//!
//! The builders are in `fixtures.rs`, which the crate's unit tests compile too (as `crate::test_fixtures`), so
//! every viewer test builds its snapshots and deltas from one place.

#![allow(dead_code)]

mod fixtures;

pub use fixtures::*;

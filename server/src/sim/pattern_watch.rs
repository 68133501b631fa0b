//! The pattern an exercise judges: how its cut stands after each tick ([`StepReport::pattern_cut`]), for the
//! training layer to score FLS's pattern-cutting task by (`training::pattern_cutting`).
//!
//! Owns: [`PatternWatch`] and [`Sim::pattern_cut_now`]. The pattern is the world's pattern-cutting exercise's
//! (`scene/exercise_spec.rs`); the reading is `tissue::pattern_cut`'s, taken again only when the sheet's topology
//! changed (a cut is an event: the reading allocates then, and only then). Must not: panic (a world without a
//! pattern reports none).

use crate::scene::PatternSpec;
use crate::tissue::Vec3;
use crate::tissue::pattern_cut::{PatternCircle, PatternCutReading, read_pattern_cut};

use super::*;

/// A pattern and its cut as last read.
#[derive(Debug, Clone)]
pub(super) struct PatternWatch {
    object: usize,
    circle: PatternCircle,
    /// The sheet's topology version the reading was taken at.
    version: Option<u32>,
    reading: Option<PatternCutReading>,
    /// Scratch: each vertex's piece.
    pieces: Vec<u32>,
}

impl PatternWatch {
    pub(super) fn new(spec: PatternSpec) -> Self {
        Self {
            object: spec.object,
            circle: PatternCircle {
                centre_mm: Vec3::from(spec.centre_mm),
                inner_radius_mm: spec.inner_radius_mm,
                outer_radius_mm: spec.outer_radius_mm,
            },
            version: None,
            reading: None,
            pieces: Vec::new(),
        }
    }
}

impl Sim {
    /// The cut of the exercise's pattern now (None: the world marks no pattern, or its sheet is gone).
    pub(super) fn pattern_cut_now(&mut self) -> Option<PatternCutReading> {
        let watch = self.pattern.as_mut()?;
        let o = self.objects.get(watch.object)?;
        if watch.version != Some(o.topology_version) {
            let model = &o.model;
            watch.reading = read_pattern_cut(
                model.rest_positions_mm(),
                model.triangles(),
                |i| model.is_fixed(i),
                &watch.circle,
                &mut watch.pieces,
            );
            watch.version = Some(o.topology_version);
        }
        watch.reading
    }
}

//! What one step did, counted: [`StepReport`].

/// What happened in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepReport {
    /// Integrator substeps run (summed over objects, retries included).
    pub substeps: u32,
    /// Times the tick was rerun with its step halved because an object diverged.
    pub retries: u32,
    /// Solver iterations (CG, XPBD sweeps, relaxation sweeps) summed over objects and substeps.
    pub solver_iterations: u32,
    /// Objects still broken (non-finite or beyond the guard's absolute limits) at the smallest step, reset to
    /// rest this step.
    pub faults: u32,
    /// Nodes held by all tools.
    pub held_nodes: u32,
    /// Nodes integrated this tick by region-tracked objects (their active regions, summed).
    pub region_nodes: u32,
    /// Region sub-models rebuilt this tick (the active set changed).
    pub region_rebuilds: u32,
    /// Grasps that took hold this tick (jaws closed on tissue touching both).
    pub grasps_taken: u32,
    /// Jaws that closed this tick without tissue on both sides.
    pub grasps_missed: u32,
    /// Points of tissue let go by opening jaws (or a tool leaving) this tick.
    pub attachments_released: u32,
    /// Points of tissue that slipped out of the jaws this tick (pulled past the grasp's slip force).
    pub attachments_slipped: u32,
    /// Nodes a cautery tool burnt this tick (summed over tools).
    pub nodes_burnt: u32,
    /// Facets scalpels' edges cut this tick (a cut opens once it separates a vertex).
    pub seams_cut: u32,
    /// Springs of sheets stretched past their material's tear strain this tick.
    pub seams_torn: u32,
    /// Vertices split off by cuts and tears this tick.
    pub vertices_split: u32,
    /// Steps a suture's holes tore through their tissue this tick (`hole_tearing.rs`).
    pub hole_tears: u32,
    /// Holes a suture cut all the way out of (its thread let go there) this tick.
    pub holes_torn_out: u32,
    /// Surfaces a needle's tip punctured this tick.
    pub punctures: u32,
    /// Surface nodes of one object watched against a face of another this tick (tissue-tissue contact).
    pub tissue_contacts: u32,
    /// Holes a needle left this tick (drawn back through them, or pulled through past its tail).
    pub needle_holes_closed: u32,
    /// How far open the wound the world's suture exercise names is after the tick, mm (None: no wound named).
    pub wound_gap_mm: Option<f32>,
    /// How the pattern the world's pattern-cutting exercise marks is cut after the tick (None: no pattern).
    pub pattern_cut: Option<crate::tissue::pattern_cut::PatternCutReading>,
}

//! The evolving state of one tissue object.

use super::{MassSpringModel, Vec3};

/// Positions and velocities of every node, the external forces acting on them, and the force scratch buffer
/// integrators reuse.
#[derive(Debug, Clone)]
pub struct TissueState {
    /// Node positions, world frame, mm.
    pub positions_mm: Vec<Vec3>,
    /// Node velocities, mm/s.
    pub velocities_mm_s: Vec<Vec3>,
    /// Scratch: total force on each node, N (written by integrators; valid after a step).
    pub forces_n: Vec<Vec3>,
    /// Forces from outside the object (ties to other objects), N; held constant over a step.
    pub external_forces_n: Vec<Vec3>,
    /// Nodes a tool holds still through the next step, sorted (empty: none). Implicit Euler solves them as
    /// fixed rows, so the rest of the tissue answers a held node where the tool holds it: with the hold applied
    /// only after the solve, the tissue around a dent relaxes toward where the held nodes would have gone, and
    /// a long step's equilibrium is off by an amount that grows with the step (a multi-rate object's 5 ms
    /// step pressed 29% harder than 1 ms steps). Explicit methods ignore it: they move a held node by
    /// `h^2 F / m`, which the tool's projection undoes.
    pub pinned: Vec<u32>,
}

impl TissueState {
    /// The model at rest.
    pub fn at_rest(model: &MassSpringModel) -> Self {
        let n = model.node_count();
        Self {
            positions_mm: model.rest_positions_mm().to_vec(),
            velocities_mm_s: vec![Vec3::zeros(); n],
            forces_n: vec![Vec3::zeros(); n],
            external_forces_n: vec![Vec3::zeros(); n],
            pinned: Vec::new(),
        }
    }

    /// Reset to rest without allocating.
    pub fn reset_to_rest(&mut self, model: &MassSpringModel) {
        self.positions_mm.copy_from_slice(model.rest_positions_mm());
        self.velocities_mm_s.fill(Vec3::zeros());
        self.forces_n.fill(Vec3::zeros());
        self.external_forces_n.fill(Vec3::zeros());
    }

    /// Every position and velocity is finite. No allocation.
    pub fn is_finite(&self) -> bool {
        let sum: f32 = self
            .positions_mm
            .iter()
            .chain(self.velocities_mm_s.iter())
            .map(|v| v.x + v.y + v.z)
            .sum();
        sum.is_finite()
    }
}

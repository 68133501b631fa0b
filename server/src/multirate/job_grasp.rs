//! A grasp on a multi-rate object, as its step job sees it: the jaws' attachments to this object, copied in at
//! launch, held every substep of the step, and their pulls measured at its end for the tick to settle (slip)
//! and render.
//!
//! Owns: [`JobGrasp`] (the attachments, the nodes they move, the grip, the pulls). Must not: take or let go of
//! points (the tick's grasper does, on the object's latest finished step), or allocate once built.

use nalgebra::UnitQuaternion;

use crate::interaction::{
    Attachment, Grasp, MAX_ATTACHMENTS, hold_points, nodes_held, point_pull_n,
};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// One tool's hold on a multi-rate object during a step.
#[derive(Debug, Clone)]
pub(crate) struct JobGrasp {
    /// The points held, all on this object (their `object` is the object's index in the world).
    attachments: Vec<Attachment>,
    /// The nodes they move, sorted (the step's probe leaves them alone).
    nodes: Vec<u32>,
    /// How firmly they are held at launch, 0..1.
    grip: f32,
    /// Per attachment, the tissue's pull on it at the end of the step, N.
    pulls: Vec<Vec3>,
}

impl JobGrasp {
    /// A grasp holding nothing.
    pub(crate) fn new() -> Self {
        let most = usize::from(MAX_ATTACHMENTS);
        Self {
            attachments: Vec::with_capacity(most),
            nodes: Vec::with_capacity(3 * most),
            grip: 0.0,
            pulls: Vec::with_capacity(most),
        }
    }

    /// Take the points of object `object` that `grasp` holds (none: `grasp` None) for the next step. No
    /// allocation.
    pub(crate) fn set(&mut self, object: usize, grasp: Option<&Grasp>, model: &MassSpringModel) {
        self.attachments.clear();
        self.pulls.clear();
        self.grip = 0.0;
        if let Some(grasp) = grasp {
            let mine = grasp
                .attachments()
                .iter()
                .filter(|a| usize::from(a.object) == object);
            self.attachments.extend(mine);
            self.grip = grasp.grip();
        }
        self.pulls.resize(self.attachments.len(), Vec3::zeros());
        nodes_held(&self.attachments, object, model, &mut self.nodes);
    }

    /// Let go of everything (the tool left, or the object was reset).
    pub(crate) fn clear(&mut self) {
        self.attachments.clear();
        self.pulls.clear();
        self.nodes.clear();
    }

    /// The nodes the points move, sorted.
    pub(crate) fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Whether it holds anything.
    pub(crate) fn holds(&self) -> bool {
        !self.attachments.is_empty()
    }

    /// One substep: move each point to its place on jaws posed at `position_mm`, `rotation`.
    pub(crate) fn hold(
        &self,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        if let Some(a) = self.attachments.first() {
            let object = usize::from(a.object);
            hold_points(
                &self.attachments,
                object,
                self.grip,
                position_mm,
                rotation,
                model,
                state,
            );
        }
    }

    /// At the end of the step: each point's pull, and their sum (not scaled by the grip: the tick scales it by
    /// the grip it has then), N.
    pub(crate) fn measure(&mut self, model: &MassSpringModel, state: &TissueState) -> Vec3 {
        let pressure = model.pressure_n_per_mm2(&state.positions_mm);
        let mut sum = Vec3::zeros();
        for (a, pull) in self.attachments.iter().zip(self.pulls.iter_mut()) {
            *pull = point_pull_n(a, model, state, pressure);
            sum += *pull;
        }
        sum
    }

    /// The pull measured on `attachment` at the end of the step (None if the step did not hold it).
    pub(crate) fn pull_of(&self, attachment: &Attachment) -> Option<Vec3> {
        self.attachments
            .iter()
            .position(|a| a == attachment)
            .map(|k| self.pulls[k])
    }
}

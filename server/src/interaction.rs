//! Tool-tissue interactions: probing, jaws, grasping, cutting and tearing, and suturing's pieces ([`suture`]);
//! and one tissue against another ([`TissuePair`]).
//!
//! Owns: turning tool contacts into node corrections and the force each tool feels ([`ProbeContacts`]), the
//! articulation of an instrument's jaws from its device's buttons or jaw angle ([`Jaws`]), and the attachments
//! a closed grasper holds ([`Grasp`]), and the seams a blade's sweep or an overstretched spring opens
//! ([`swept_seams`], [`torn_seams`]), and the contact forces that keep one object's surface out of another's
//! ([`TissuePair`]). Must not: integrate the tissue (that is [`crate::tissue`]) or find
//! candidates (that is [`crate::collision`]).

mod blade_path;
mod cut;
mod grasp;
mod instrument;
mod jaws;
mod probe;
pub mod suture;
mod tissue_pair;

pub use blade_path::{BladePath, HISTORY_SWEEPS};
pub use cut::{BladeSweep, CutScratch, swept_seams, torn_seams};
pub use grasp::{Attachment, Grasp, GraspEvent, MAX_ATTACHMENTS};
pub(crate) use grasp::{hold_points, nodes_held, point_pull_n};
pub use instrument::{
    CauterySpec, GraspSpec, InstrumentSpec, JawActivation, ScalpelSpec, ScissorsSpec,
};
pub use jaws::{JawInput, Jaws};
pub use probe::{ProbeContacts, ToolBody, add_node_reaction};
pub use tissue_pair::{PairSide, TissuePair};

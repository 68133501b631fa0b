//! The instruments, one file each, behind [`super::instrument::Instrument`].
//!
//! Owns: nothing but the list. Must not: share state between instruments (what two share, such as a blade's
//! drag, is a plain helper in its own file).

mod blade_drag;
mod cautery_tip;
mod grasper;
mod needle_driver;
mod scalpel;
mod scissors;

pub(super) use cautery_tip::CauteryTip;
pub(super) use grasper::Grasper;
pub(super) use needle_driver::NeedleDriver;
pub(super) use scalpel::Scalpel;
pub(super) use scissors::Scissors;

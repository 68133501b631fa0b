//! Tie-nodes: spring-dampers that link nodes of one object to nodes of another (skin on bone), so forces
//! pass between objects that are integrated separately.
//!
//! A tie set is built by the world loader (each node of the first object tied to the nearest node of the
//! second within a radius); each substep it writes equal and opposite forces into both objects'
//! `external_forces_n`. No allocation, never panics.

use super::{TissueState, Vec3};

/// Ties between two objects.
#[derive(Debug, Clone, PartialEq)]
pub struct TieSet {
    /// Index of the first object.
    pub object_a: usize,
    /// Index of the second object.
    pub object_b: usize,
    /// (node in a, node in b, rest offset b - a in mm).
    pub pairs: Vec<(u32, u32, Vec3)>,
    /// Stiffness of each tie, N/mm.
    pub stiffness_n_per_mm: f32,
    /// Damping of each tie, N s/mm.
    pub damping_n_s_per_mm: f32,
}

impl TieSet {
    /// Add the tie forces to both objects' external forces (the caller zeroes them once per substep).
    pub fn accumulate(&self, a: &mut TissueState, b: &mut TissueState) {
        for &(na, nb, rest_offset) in &self.pairs {
            let (na, nb) = (na as usize, nb as usize);
            let stretch = (b.positions_mm[nb] - a.positions_mm[na]) - rest_offset;
            let rate = b.velocities_mm_s[nb] - a.velocities_mm_s[na];
            let f = stretch * self.stiffness_n_per_mm + rate * self.damping_n_s_per_mm;
            if f.iter().all(|c| c.is_finite()) {
                a.external_forces_n[na] += f;
                b.external_forces_n[nb] -= f;
            }
        }
    }

    /// Elastic energy stored in the ties, N mm.
    pub fn energy_n_mm(&self, a: &TissueState, b: &TissueState) -> f64 {
        self.pairs
            .iter()
            .map(|&(na, nb, rest_offset)| {
                let stretch =
                    (b.positions_mm[nb as usize] - a.positions_mm[na as usize]) - rest_offset;
                f64::from(0.5 * self.stiffness_n_per_mm * stretch.norm_squared())
            })
            .sum()
    }
}

//! A 1-D rod (a suture thread): nodes along a polyline joined by stretch springs between neighbours and bend
//! springs across every inner node, built as a [`MassSpringModel`] with no triangles. It is stepped by the
//! same integrators ([`super::integrator_for`]) and judged by the same guard ([`super::step_guarded`],
//! [`super::DivergenceGuard`]) as a surface or a volume.
//!
//! Owns: [`RodSpec`] (the rod as the engine takes it, from a scene built in code) and its build into
//! [`ModelParts`]. Must not: collide or attach (a rod's contacts and stitches are the interaction layer's).
//!
//! The model. Segment `i` (nodes `i`, `i + 1`) is a spring of stiffness `EA / l_i` (axial rigidity over its
//! rest length). A bend spring joins nodes `i - 1` and `i + 1` with stiffness `bend_stiffness_n_per_mm`: it
//! resists folding at finite angles but, across a straight rest shape, adds no first-order bending stiffness
//! (the known limit of spring-based bending; a discrete elastic rod with curvature and twist is the upgrade
//! when a knot needs it). Masses are lumped: each node carries half of each adjacent segment's
//! `mass_per_length * l`. No anchors (a thread has no tissue under it).

use thiserror::Error;

use super::mass_spring::{MassSpringModel, ModelParts};
use super::{SpringLaw, Vec3};

/// A rod as the engine takes it.
#[derive(Debug, Clone, PartialEq)]
pub struct RodSpec {
    /// Name (key segment).
    pub name: String,
    /// Rest shape: the nodes in order along the rod, mm (at least two).
    pub nodes_mm: Vec<[f32; 3]>,
    /// Mass per length, kg/mm (a 3-0 braided suture is about 1e-7 kg/mm).
    pub mass_per_length_kg_per_mm: f32,
    /// Axial rigidity `EA`, N: a segment of rest length `l` mm stretches `F l / EA` mm under `F` N.
    pub axial_rigidity_n: f32,
    /// Stiffness of each bend spring (across one node), N/mm (0: a chain that folds freely).
    pub bend_stiffness_n_per_mm: f32,
    /// Damping along every spring, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// Viscous drag on every node, 1/s.
    pub drag_per_s: f32,
    /// Nodes held in place (indices into `nodes_mm`).
    pub fixed_nodes: Vec<u32>,
}

/// Why a rod was refused. Nothing is built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RodError {
    /// Fewer than two nodes.
    #[error("rod `{0}`: a rod needs at least two nodes")]
    TooFewNodes(String),
    /// A node with a NaN or infinite coordinate.
    #[error("rod `{name}`: node {node} has a non-finite coordinate")]
    NonFinite {
        /// Rod name.
        name: String,
        /// Node index.
        node: usize,
    },
    /// Two consecutive nodes at the same place.
    #[error("rod `{name}`: segment {segment} has zero length")]
    ZeroSegment {
        /// Rod name.
        name: String,
        /// Segment index (nodes `segment`, `segment + 1`).
        segment: usize,
    },
    /// A material number out of range.
    #[error("rod `{name}`: {key} must be {expected}, got {value}")]
    Material {
        /// Rod name.
        name: String,
        /// The field.
        key: &'static str,
        /// What it must be.
        expected: &'static str,
        /// What it was.
        value: f32,
    },
    /// A fixed node index past the last node.
    #[error("rod `{name}`: fixed node {node} does not exist (the rod has {nodes} nodes)")]
    FixedOutOfRange {
        /// Rod name.
        name: String,
        /// The index given.
        node: u32,
        /// Nodes in the rod.
        nodes: usize,
    },
}

impl RodSpec {
    /// A straight rod from `from_mm` to `to_mm` in `segments` equal segments, with a 3-0 suture's material
    /// (about 1e-7 kg/mm, EA 50 N, light bend springs, damping and drag) and no fixed node.
    pub fn straight(name: &str, from_mm: [f32; 3], to_mm: [f32; 3], segments: u32) -> Self {
        let (a, b) = (Vec3::from(from_mm), Vec3::from(to_mm));
        let nodes_mm = (0..=segments)
            .map(|k| {
                let p = a + (b - a) * (k as f32 / segments.max(1) as f32);
                [p.x, p.y, p.z]
            })
            .collect();
        Self {
            name: name.to_owned(),
            nodes_mm,
            mass_per_length_kg_per_mm: 1e-7,
            axial_rigidity_n: 50.0,
            bend_stiffness_n_per_mm: 1e-3,
            damping_n_s_per_mm: 1e-5,
            drag_per_s: 2.0,
            fixed_nodes: Vec::new(),
        }
    }

    /// Rest length along the nodes, mm.
    pub fn length_mm(&self) -> f32 {
        self.nodes_mm
            .windows(2)
            .map(|w| (Vec3::from(w[1]) - Vec3::from(w[0])).norm())
            .sum()
    }

    /// How far from rest the guard lets a node of this rod travel, mm: twice its length (a rod held at one
    /// point stays within its length of that point). A thread carried free through the scene (by a needle)
    /// will need the guard measured against what holds it instead.
    pub fn guard_reach_mm(&self) -> f32 {
        2.0 * self.length_mm()
    }

    /// The rod's model parts (stretch springs first, in segment order, then bend springs), under
    /// `gravity_mm_per_s2`. Refuses a rod it cannot build faithfully, naming the field.
    pub fn parts(&self, gravity_mm_per_s2: Vec3) -> Result<ModelParts, RodError> {
        let name = || self.name.clone();
        let n = self.nodes_mm.len();
        if n < 2 {
            return Err(RodError::TooFewNodes(name()));
        }
        if let Some(node) = self
            .nodes_mm
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(RodError::NonFinite { name: name(), node });
        }
        let material = |key, value: f32, positive: bool| {
            let ok = value.is_finite() && if positive { value > 0.0 } else { value >= 0.0 };
            if ok {
                Ok(())
            } else {
                Err(RodError::Material {
                    name: name(),
                    key,
                    expected: if positive {
                        "positive"
                    } else {
                        "zero or positive"
                    },
                    value,
                })
            }
        };
        material(
            "mass_per_length_kg_per_mm",
            self.mass_per_length_kg_per_mm,
            true,
        )?;
        material("axial_rigidity_n", self.axial_rigidity_n, true)?;
        material(
            "bend_stiffness_n_per_mm",
            self.bend_stiffness_n_per_mm,
            false,
        )?;
        material("damping_n_s_per_mm", self.damping_n_s_per_mm, false)?;
        material("drag_per_s", self.drag_per_s, false)?;
        if let Some(&node) = self.fixed_nodes.iter().find(|&&i| i as usize >= n) {
            return Err(RodError::FixedOutOfRange {
                name: name(),
                node,
                nodes: n,
            });
        }
        let rest: Vec<Vec3> = self.nodes_mm.iter().map(|p| Vec3::from(*p)).collect();
        let mut mass_kg = vec![0.0f32; n];
        let mut edges = Vec::with_capacity(2 * n);
        let mut stiffness = Vec::with_capacity(2 * n);
        for segment in 0..n - 1 {
            let length_mm = (rest[segment + 1] - rest[segment]).norm();
            if length_mm <= 0.0 {
                return Err(RodError::ZeroSegment {
                    name: name(),
                    segment,
                });
            }
            let half_kg = 0.5 * self.mass_per_length_kg_per_mm * length_mm;
            mass_kg[segment] += half_kg;
            mass_kg[segment + 1] += half_kg;
            edges.push([segment as u32, segment as u32 + 1]);
            stiffness.push(self.axial_rigidity_n / length_mm);
        }
        if self.bend_stiffness_n_per_mm > 0.0 {
            for inner in 1..n - 1 {
                edges.push([inner as u32 - 1, inner as u32 + 1]);
                stiffness.push(self.bend_stiffness_n_per_mm);
            }
        }
        let mut fixed = vec![false; n];
        for &i in &self.fixed_nodes {
            fixed[i as usize] = true;
        }
        Ok(ModelParts {
            rest_positions_mm: rest,
            mass_kg,
            fixed,
            edge_damping_n_s_per_mm: vec![self.damping_n_s_per_mm; edges.len()],
            edge_stiffness_n_per_mm: stiffness,
            edges,
            law: Some(SpringLaw::Linear),
            anchor_stiffness_n_per_mm: 0.0,
            drag_per_s: self.drag_per_s,
            gravity_mm_per_s2,
            ..ModelParts::default()
        })
    }

    /// The rod's model (see [`Self::parts`]). Allocates (a scene is being built).
    pub fn model(&self, gravity_mm_per_s2: Vec3) -> Result<MassSpringModel, RodError> {
        Ok(MassSpringModel::from_parts(self.parts(gravity_mm_per_s2)?))
    }
}

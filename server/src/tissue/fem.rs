//! Corotational linear finite elements on tetrahedra: tissue from Young's modulus and Poisson's ratio.
//!
//! Owns: the elastic material ([`FemMaterial`]), each tetrahedron's rest shape (`Dm^-1`, rest volume), each
//! node's rest volume share, the element forces, their energy, and the linearisation the implicit integrator
//! solves with ([`FemLinearization`]). Must not: know about tools, time stepping or the world file.
//!
//! The model. Each tetrahedron has a constant deformation gradient `F = Ds Dm^-1` (`Ds`, `Dm` the edge matrices
//! now and at rest). Its rotation `R` comes from the polar decomposition `F = R S` ([`rotation_of`]); the
//! strain is measured in the element's rotated frame, `e = sym(R^T F) - I`, so a rigid rotation strains
//! nothing (Müller and Gross, "Interactive virtual materials", GI 2004; Irving, Teran and Fedkiw's
//! rotated linear elasticity). With [`FemMaterial::corotated`] off, `R = I`: plain linear elasticity,
//! which a large rotation strains (kept to show why corotation is needed).
//!
//! Near-incompressibility without locking. A linear tetrahedron has one volume: at Poisson's ratio near 0.5
//! its volumetric stiffness pins the mesh (volumetric locking). So the stress is split. The deviatoric part
//! `2 mu dev(e)` lives in each element; the volumetric part is the average-nodal-pressure tetrahedron of
//! Bonet and Burton ("A simple average nodal pressure tetrahedral element for incompressible and nearly
//! incompressible dynamic explicit applications", Commun. Numer. Meth. Engng 14, 1998): each node `a` owns a
//! quarter of every tetrahedron around it, `V_a = sum V_t / 4`, with energy `kappa (V_a - V_a0)^2 / (2 V_a0)`
//! (`kappa` the bulk modulus), so there is one volume constraint per node instead of per element, and
//! each element feels its nodes' mean pressure. Volumes do not change under rotation, so this part is
//! rotation-invariant by construction; it passes the patch test (a homogeneous strain gives the exact
//! stress), so a uniaxial test recovers `E` and `nu` exactly at small strain.
//!
//! Units: mm, N, N/mm^2 (1 kPa = 1e-3 N/mm^2). Real-time contract: no allocation once warm (the scratch grows
//! on first use with a model of this size), never panics on non-finite input.
//!
//! Here: the material, each element's rest data ([`FemElements::refill`]) and its accessors, and the small
//! helpers the parts share. The rest, by idea: `polar` (each element's rotation), `forces` (the force
//! pass and the energy), `linearization` (the frozen stiffness the implicit integrator solves with).

#![allow(clippy::needless_range_loop)] // loops walk several parallel per-node arrays by index

use nalgebra::Matrix3;
use sinew_parallel::ScratchCell;

use super::Vec3;
use super::volume::{TetVolumes, tet_volume_gradients};

mod forces;
mod linearization;
mod polar;
#[cfg(test)]
mod tests;

pub use linearization::element_deviatoric_product;
pub use polar::rotation_of;

/// An isotropic elastic material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FemMaterial {
    /// Young's modulus, N/mm^2 (1 kPa = 1e-3 N/mm^2).
    pub youngs_modulus_n_per_mm2: f32,
    /// Poisson's ratio, below 0.5.
    pub poisson_ratio: f32,
    /// Strain in each element's rotated frame (corotational); `false`: plain linear elasticity.
    pub corotated: bool,
}

impl FemMaterial {
    /// Shear modulus `mu = E / (2 (1 + nu))`, N/mm^2.
    pub fn shear_modulus_n_per_mm2(&self) -> f32 {
        self.youngs_modulus_n_per_mm2 / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Bulk modulus `kappa = E / (3 (1 - 2 nu))`, N/mm^2.
    pub fn bulk_modulus_n_per_mm2(&self) -> f32 {
        self.youngs_modulus_n_per_mm2 / (3.0 * (1.0 - 2.0 * self.poisson_ratio))
    }
}

/// The tetrahedra around each node, as compressed rows: node `i`'s are `tets[start[i]..start[i + 1]]`.
#[derive(Debug, Clone, Copy)]
pub struct NodeTets<'a> {
    /// Row starts, one per node plus one.
    pub start: &'a [u32],
    /// Tetrahedron indices.
    pub tets: &'a [u32],
}

impl NodeTets<'_> {
    /// The tetrahedra around node `i`.
    #[inline(always)]
    pub fn of(&self, i: usize) -> &[u32] {
        match (self.start.get(i), self.start.get(i + 1)) {
            (Some(&a), Some(&b)) => self.tets.get(a as usize..b as usize).unwrap_or(&[]),
            _ => &[],
        }
    }
}

/// Per-tetrahedron state of a linearisation: the rotation of each element and its volume gradients at the
/// positions it was made at, plus a per-node scratch.
#[derive(Debug, Clone, Default)]
pub struct FemLinearization {
    rotations: Vec<Matrix3<f32>>,
    gradients: Vec<[Vec3; 4]>,
    node_sum: Vec<f32>,
}

impl FemLinearization {
    /// Each element's rotation frozen at the step's start (empty when the model has no elements).
    pub fn rotations(&self) -> &[Matrix3<f32>] {
        &self.rotations
    }

    /// Empty, with the per-node scratch sized for `nodes`.
    fn clear(&mut self, nodes: usize) {
        self.rotations.clear();
        self.gradients.clear();
        self.node_sum.clear();
        self.node_sum.resize(nodes, 0.0);
    }
}

/// Per-node scratch of a force pass.
#[derive(Debug, Clone, Default)]
struct FemScratch {
    node_volume_mm3: Vec<f32>,
    node_pressure_n_per_mm2: Vec<f32>,
}

/// The finite elements of one object (empty when the object is a pure mass-spring model).
#[derive(Debug, Clone, Default)]
pub struct FemElements {
    material: Option<FemMaterial>,
    shear_n_per_mm2: f32,
    bulk_n_per_mm2: f32,
    /// `Dm^-1` of each tetrahedron (same order as [`TetVolumes::tets`]), 1/mm.
    rest_inverse: Vec<Matrix3<f32>>,
    /// Each node's share of the rest volume, mm^3 (0 for a node on no tetrahedron).
    node_rest_volume_mm3: Vec<f32>,
    /// An isotropic estimate of each node's stiffness diagonal at rest, N/mm.
    node_diagonal_n_per_mm: Vec<f32>,
    /// Gershgorin bound on each node's row of the rest stiffness, N/mm.
    node_row_bound_n_per_mm: Vec<f32>,
    scratch: ScratchCell<FemScratch>,
}

impl FemElements {
    /// Refill from the model's tetrahedra (oriented, degenerate ones dropped) and rest positions; `None`:
    /// no elements. Allocates only where this model is larger than any before.
    pub fn refill(&mut self, material: Option<FemMaterial>, tets: &TetVolumes, rest_mm: &[Vec3]) {
        self.material = material;
        self.rest_inverse.clear();
        self.node_rest_volume_mm3.clear();
        self.node_diagonal_n_per_mm.clear();
        self.node_row_bound_n_per_mm.clear();
        let Some(material) = material else {
            self.shear_n_per_mm2 = 0.0;
            self.bulk_n_per_mm2 = 0.0;
            return;
        };
        let n = rest_mm.len();
        self.shear_n_per_mm2 = material.shear_modulus_n_per_mm2();
        self.bulk_n_per_mm2 = material.bulk_modulus_n_per_mm2();
        self.node_rest_volume_mm3.resize(n, 0.0);
        self.node_diagonal_n_per_mm.resize(n, 0.0);
        self.node_row_bound_n_per_mm.resize(n, 0.0);
        let (mu, kappa) = (self.shear_n_per_mm2, self.bulk_n_per_mm2);
        for (t, tet) in tets.tets.iter().enumerate() {
            let [a, b, c, d] = tet.map(|i| rest_mm[i as usize]);
            let dm = Matrix3::from_columns(&[b - a, c - a, d - a]);
            let inverse = dm.try_inverse().unwrap_or_else(Matrix3::zeros);
            self.rest_inverse.push(inverse);
            let v0 = tets.rest_volume_mm3[t];
            let gradients = tet_volume_gradients(rest_mm, *tet);
            // Row bound: a deviatoric block's norm is at most mu V0 (2 + 2/3) |b_i| |b_j|; the nodal volume term
            // is bounded by the per-element one (Cauchy-Schwarz), kappa / V0 |g_i| |g_j|.
            let b_norm: [f32; 4] = std::array::from_fn(|k| shape_gradient(&inverse, k).norm());
            let g_norm = gradients.map(|g| g.norm());
            let (b_sum, g_sum): (f32, f32) = (b_norm.iter().sum(), g_norm.iter().sum());
            for (k, &i) in tet.iter().enumerate() {
                self.node_row_bound_n_per_mm[i as usize] +=
                    mu * v0 * (8.0 / 3.0) * b_norm[k] * b_sum + kappa / v0 * g_norm[k] * g_sum;
                self.node_rest_volume_mm3[i as usize] += v0 / 4.0;
                // Shape gradient of node k: rows of Dm^-1 (and minus their sum for the first node).
                let b_k = shape_gradient(&inverse, k);
                // Deviatoric block trace / 3 = (10/9) mu V0 |b|^2; volumetric: kappa / V0 |dV/dx|^2 / 3
                // (the per-element bound of the nodal term, an overestimate that keeps Jacobi safe).
                self.node_diagonal_n_per_mm[i as usize] +=
                    10.0 / 9.0 * mu * v0 * b_k.norm_squared()
                        + kappa / v0 * gradients[k].norm_squared() / 3.0;
            }
        }
    }

    /// Whether this object has elements.
    pub fn is_on(&self) -> bool {
        self.material.is_some()
    }

    /// The material, if on.
    pub fn material(&self) -> Option<FemMaterial> {
        self.material
    }

    /// An isotropic estimate of node `i`'s stiffness diagonal, N/mm (0 when off).
    pub fn node_diagonal_n_per_mm(&self, i: usize) -> f32 {
        self.node_diagonal_n_per_mm.get(i).copied().unwrap_or(0.0)
    }

    /// Bulk modulus of the nodal volume term, N/mm^2 (0 when off).
    pub fn bulk_modulus_n_per_mm2(&self) -> f32 {
        self.bulk_n_per_mm2
    }

    /// Node `i`'s share of the rest volume, mm^3 (0 for a node on no tetrahedron, or when off).
    pub fn node_rest_volume_mm3(&self, i: usize) -> f32 {
        self.node_rest_volume_mm3.get(i).copied().unwrap_or(0.0)
    }

    /// Rotation of element `t` (vertices `tet`) at `x` (identity when not corotated).
    #[inline(always)]
    pub fn rotation(&self, t: usize, tet: [u32; 4], x: &[Vec3]) -> Matrix3<f32> {
        let corotated = self.material.is_some_and(|m| m.corotated);
        if corotated {
            rotation_of(&(edge_matrix(tet, x) * self.rest_inverse[t]))
        } else {
            Matrix3::identity()
        }
    }

    /// `Dm^-1` of element `t`, 1/mm (zero when off or out of range).
    pub fn rest_inverse(&self, t: usize) -> Matrix3<f32> {
        self.rest_inverse
            .get(t)
            .copied()
            .unwrap_or_else(Matrix3::zeros)
    }

    /// Shear modulus, N/mm^2 (0 when off).
    pub fn shear_modulus_n_per_mm2(&self) -> f32 {
        self.shear_n_per_mm2
    }

    /// Gershgorin bound on node `i`'s row of the rest stiffness, N/mm (0 when off): the stability analysis.
    pub fn node_row_bound_n_per_mm(&self, i: usize) -> f32 {
        self.node_row_bound_n_per_mm.get(i).copied().unwrap_or(0.0)
    }
}

/// `[x1 - x0, x2 - x0, x3 - x0]` of a tetrahedron, as columns.
#[inline(always)]
fn edge_matrix(tet: [u32; 4], x: &[Vec3]) -> Matrix3<f32> {
    let [a, b, c, d] = tet.map(|i| x[i as usize]);
    Matrix3::from_columns(&[b - a, c - a, d - a])
}

/// Gradient of node `k`'s linear shape function: row `k - 1` of `Dm^-1`, and minus their sum for node 0.
#[inline(always)]
pub(crate) fn shape_gradient(inverse: &Matrix3<f32>, k: usize) -> Vec3 {
    if k == 0 {
        -(inverse.row(0) + inverse.row(1) + inverse.row(2)).transpose()
    } else {
        inverse.row(k - 1).transpose()
    }
}

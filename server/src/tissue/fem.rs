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

#![allow(clippy::needless_range_loop)] // loops walk several parallel per-node arrays by index

use sinew_parallel::ScratchCell;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

use super::Vec3;
use super::volume::{TetVolumes, tet_volume_gradients, tet_volume_mm3};

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

/// Most Newton polar-decomposition iterations per element (two to four reach f32 precision at tissue strains).
const POLAR_ITERATIONS: usize = 8;

/// Most iterations of the robust polar decomposition (inverted or flat elements only; it converges linearly).
const ROBUST_ITERATIONS: usize = 32;

/// The rotation of `f`'s polar decomposition `f = R S`. An element that is neither inverted nor nearly flat
/// takes Higham's Newton iteration (converged to 1e-6); any other takes the iteration of Müller, Bender,
/// Chentanez and Macklin ("A robust method to extract the rotational part of deformations", MIG 2016),
/// started from the Gram-Schmidt frame of `f`'s first two columns, which always gives a rotation. A pure
/// function of `f`: the same input gives the same bits, so forces never depend on history.
pub fn rotation_of(f: &Matrix3<f32>) -> Matrix3<f32> {
    // The common case, an element that is not inverted or flat: Higham's Newton iteration
    // `R <- (R + R^-T) / 2` from `R = F`, quadratic (two to four iterations at tissue strains).
    let det = f.determinant();
    if det > 1e-3 * f.norm_squared().powf(1.5) {
        let mut r = *f;
        for _ in 0..POLAR_ITERATIONS {
            let Some(inverse) = r.try_inverse() else {
                break;
            };
            let next = (r + inverse.transpose()) * 0.5;
            let change = (next - r).norm_squared();
            if !change.is_finite() {
                break;
            }
            r = next;
            if change < 1e-12 {
                return r;
            }
        }
    }
    rotation_of_any(f)
}

/// [`rotation_of`] for any `f`, also inverted or degenerate: Müller et al.'s iteration from the Gram-Schmidt
/// frame of `f`'s first two columns.
fn rotation_of_any(f: &Matrix3<f32>) -> Matrix3<f32> {
    let (c0, c1) = (f.column(0).into_owned(), f.column(1).into_owned());
    let guess = c0.try_normalize(1e-20).and_then(|e0| {
        let e1 = (c1 - e0 * e0.dot(&c1)).try_normalize(1e-20)?;
        Some(Matrix3::from_columns(&[e0, e1, e0.cross(&e1)]))
    });
    // Closed form from an orthonormal frame (`UnitQuaternion::from_matrix` would iterate from the identity).
    let mut q = match guess {
        Some(m) => UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
        None => UnitQuaternion::identity(),
    };
    if !q.coords.iter().all(|c| c.is_finite()) {
        q = UnitQuaternion::identity();
    }
    for _ in 0..ROBUST_ITERATIONS {
        let r = q.to_rotation_matrix().into_inner();
        let mut axis = Vec3::zeros();
        let mut denom = 0.0;
        for k in 0..3 {
            let (rk, fk) = (r.column(k), f.column(k));
            axis += rk.cross(&fk);
            denom += rk.dot(&fk);
        }
        let omega = axis / (denom.abs() + 1e-9);
        // Converged (or not finite): 1e-6 rad is below what f32 strains resolve.
        let turn_squared = omega.norm_squared();
        if turn_squared.is_nan() || turn_squared < 1e-12 {
            break;
        }
        // Turn by `omega` (first order: the quaternion (1, omega / 2), renormalised; no trigonometry).
        let turn = nalgebra::Quaternion::new(1.0, omega.x * 0.5, omega.y * 0.5, omega.z * 0.5);
        q = UnitQuaternion::new_normalize(turn * q.into_inner());
    }
    q.to_rotation_matrix().into_inner()
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

/// `sym(m) - I` with its trace removed: the deviatoric small strain of a rotated gradient `m`.
#[inline(always)]
fn deviatoric_strain(m: &Matrix3<f32>) -> Matrix3<f32> {
    let e = (m + m.transpose()) * 0.5 - Matrix3::identity();
    let mean = e.trace() / 3.0;
    e - Matrix3::from_diagonal_element(mean)
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

    /// Deviatoric force of element `t` on its four nodes, N, and the element's rotation.
    #[inline(always)]
    fn deviatoric_forces(
        &self,
        t: usize,
        tet: [u32; 4],
        v0: f32,
        x: &[Vec3],
    ) -> ([Vec3; 4], Matrix3<f32>) {
        let inverse = &self.rest_inverse[t];
        let f = edge_matrix(tet, x) * inverse;
        let r = if self.material.is_some_and(|m| m.corotated) {
            rotation_of(&f)
        } else {
            Matrix3::identity()
        };
        let stress = deviatoric_strain(&(r.transpose() * f)) * (2.0 * self.shear_n_per_mm2);
        let h = -(r * stress * inverse.transpose()) * v0;
        let (f1, f2, f3) = (
            h.column(0).into_owned(),
            h.column(1).into_owned(),
            h.column(2).into_owned(),
        );
        ([-(f1 + f2 + f3), f1, f2, f3], r)
    }

    /// Add every element's force at `x` to `forces_n`; with `lin`, also freeze the elements' rotations and
    /// volume gradients there, as [`Self::linearize`] does (one polar decomposition per element for both).
    pub fn accumulate_forces(
        &self,
        tets: &TetVolumes,
        x: &[Vec3],
        forces_n: &mut [Vec3],
        mut lin: Option<&mut FemLinearization>,
    ) {
        if let Some(lin) = lin.as_deref_mut() {
            lin.clear(self.node_rest_volume_mm3.len());
        }
        if !self.is_on() {
            return;
        }
        self.scratch
            .with(|scratch| self.accumulate_with(tets, x, forces_n, lin, scratch));
    }

    fn accumulate_with(
        &self,
        tets: &TetVolumes,
        x: &[Vec3],
        forces_n: &mut [Vec3],
        mut lin: Option<&mut FemLinearization>,
        scratch: &mut FemScratch,
    ) {
        self.node_pressures(tets, x, scratch);
        for (t, &tet) in tets.tets.iter().enumerate() {
            let v0 = tets.rest_volume_mm3[t];
            let (deviatoric, rotation) = self.deviatoric_forces(t, tet, v0, x);
            let gradients = tet_volume_gradients(x, tet);
            if let Some(lin) = lin.as_deref_mut() {
                lin.rotations.push(rotation);
                lin.gradients.push(gradients);
            }
            let mean_pressure = tet
                .iter()
                .map(|&i| scratch.node_pressure_n_per_mm2[i as usize])
                .sum::<f32>()
                / 4.0;
            for (k, &i) in tet.iter().enumerate() {
                forces_n[i as usize] += deviatoric[k] + gradients[k] * mean_pressure;
            }
        }
    }

    /// Every node's volume and pressure `-kappa (V_a - V_a0) / V_a0` at `x` into `scratch`.
    fn node_pressures(&self, tets: &TetVolumes, x: &[Vec3], scratch: &mut FemScratch) {
        let n = self.node_rest_volume_mm3.len();
        scratch.node_volume_mm3.clear();
        scratch.node_volume_mm3.resize(n, 0.0);
        for &tet in &tets.tets {
            let quarter = tet_volume_mm3(x, tet) / 4.0;
            for &i in &tet {
                scratch.node_volume_mm3[i as usize] += quarter;
            }
        }
        scratch.node_pressure_n_per_mm2.clear();
        scratch.node_pressure_n_per_mm2.extend(
            scratch
                .node_volume_mm3
                .iter()
                .zip(&self.node_rest_volume_mm3)
                .map(|(&v, &v0)| {
                    if v0 > 0.0 {
                        -self.bulk_n_per_mm2 * (v - v0) / v0
                    } else {
                        0.0
                    }
                }),
        );
    }

    /// Pressure of node `a` at `x` from its own tetrahedra (`node_tets.of(a)`), N/mm^2. No allocation.
    fn node_pressure(
        &self,
        a: usize,
        tets: &TetVolumes,
        node_tets: NodeTets<'_>,
        x: &[Vec3],
    ) -> f32 {
        let v0 = self.node_rest_volume_mm3[a];
        if v0 <= 0.0 {
            return 0.0;
        }
        let v: f32 = node_tets
            .of(a)
            .iter()
            .map(|&t| tet_volume_mm3(x, tets.tets[t as usize]) / 4.0)
            .sum();
        -self.bulk_n_per_mm2 * (v - v0) / v0
    }

    /// Elastic force on node `i` alone at `x`, N: its elements' deviatoric forces and the nodal pressures
    /// of their nodes (two rings of tetrahedra). No allocation.
    pub fn node_force(
        &self,
        i: usize,
        tets: &TetVolumes,
        node_tets: NodeTets<'_>,
        x: &[Vec3],
    ) -> Vec3 {
        let mut force = Vec3::zeros();
        if !self.is_on() {
            return force;
        }
        for &t in node_tets.of(i) {
            let t = t as usize;
            let tet = tets.tets[t];
            let Some(k) = tet.iter().position(|&v| v as usize == i) else {
                continue;
            };
            force += self.deviatoric_forces(t, tet, tets.rest_volume_mm3[t], x).0[k];
            let mean_pressure = tet
                .iter()
                .map(|&a| self.node_pressure(a as usize, tets, node_tets, x))
                .sum::<f32>()
                / 4.0;
            force += tet_volume_gradients(x, tet)[k] * mean_pressure;
        }
        force
    }

    /// Elastic energy at `x`, N mm: `mu V0 |dev e|^2` per element plus `kappa (V_a - V_a0)^2 / (2 V_a0)` per
    /// node.
    pub fn energy_n_mm(&self, tets: &TetVolumes, x: &[Vec3]) -> f64 {
        if !self.is_on() {
            return 0.0;
        }
        let mut total = 0.0f64;
        for (t, &tet) in tets.tets.iter().enumerate() {
            let f = edge_matrix(tet, x) * self.rest_inverse[t];
            let r = self.rotation(t, tet, x);
            let e = deviatoric_strain(&(r.transpose() * f));
            total += f64::from(self.shear_n_per_mm2 * tets.rest_volume_mm3[t] * e.norm_squared());
        }
        self.scratch.with(|scratch| {
            self.node_pressures(tets, x, scratch);
            for (&v, &v0) in scratch
                .node_volume_mm3
                .iter()
                .zip(&self.node_rest_volume_mm3)
            {
                if v0 > 0.0 {
                    total += f64::from(0.5 * self.bulk_n_per_mm2 * (v - v0) * (v - v0) / v0);
                }
            }
        });
        total
    }

    /// Freeze each element's rotation and volume gradients at `x` into `lin` (the corotational stiffness
    /// `R K0 R^T` and the Gauss-Newton nodal-volume term the implicit integrator solves with).
    pub fn linearize(&self, tets: &TetVolumes, x: &[Vec3], lin: &mut FemLinearization) {
        lin.clear(self.node_rest_volume_mm3.len());
        if !self.is_on() {
            return;
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            lin.rotations.push(self.rotation(t, tet, x));
            lin.gradients.push(tet_volume_gradients(x, tet));
        }
    }

    /// `out += scale K p` with `K` the stiffness frozen in `lin` (made by [`Self::linearize`] on this model).
    pub fn add_stiffness_product(
        &self,
        tets: &TetVolumes,
        lin: &mut FemLinearization,
        p: &[Vec3],
        scale: f32,
        out: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            let v0 = tets.rest_volume_mm3[t] * scale;
            let y = self.deviatoric_product(t, &lin.rotations[t], &tet.map(|i| p[i as usize]), v0);
            for (k, &i) in tet.iter().enumerate() {
                out[i as usize] += y[k];
            }
        }
        self.add_volume_product(tets, lin, p, scale, out);
    }

    /// `out += scale K_vol p`: the nodal volume term's part of [`Self::add_stiffness_product`] alone (the
    /// deviatoric part may come assembled instead: [`super::fem_assembly`]).
    pub fn add_volume_product(
        &self,
        tets: &TetVolumes,
        lin: &mut FemLinearization,
        p: &[Vec3],
        scale: f32,
        out: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        // Nodal volumes: K_vol p = sum_a kappa / V_a0 g_a (g_a . p), g_a = sum_{t around a} dV_t/dx / 4.
        lin.node_sum.iter_mut().for_each(|s| *s = 0.0);
        for (t, &tet) in tets.tets.iter().enumerate() {
            let g = &lin.gradients[t];
            let q: f32 = (0..4).map(|k| g[k].dot(&p[tet[k] as usize])).sum::<f32>() / 4.0;
            for &a in &tet {
                lin.node_sum[a as usize] += q;
            }
        }
        for (s, &v0) in lin.node_sum.iter_mut().zip(&self.node_rest_volume_mm3) {
            *s = if v0 > 0.0 {
                *s * self.bulk_n_per_mm2 / v0
            } else {
                0.0
            };
        }
        for (t, &tet) in tets.tets.iter().enumerate() {
            let g = &lin.gradients[t];
            let w: f32 = tet.iter().map(|&a| lin.node_sum[a as usize]).sum::<f32>() * (scale / 4.0);
            for k in 0..4 {
                out[tet[k] as usize] += g[k] * w;
            }
        }
    }

    /// Element `t`'s deviatoric stiffness (its rotation `r` frozen, rest volume `v0_mm3`) times its four
    /// nodes' displacements `p`: the element's part of `K p`, N per node.
    #[inline(always)]
    fn deviatoric_product(
        &self,
        t: usize,
        r: &Matrix3<f32>,
        p: &[Vec3; 4],
        v0_mm3: f32,
    ) -> [Vec3; 4] {
        element_deviatoric_product(
            &self.rest_inverse[t],
            r,
            p,
            2.0 * self.shear_n_per_mm2 * v0_mm3,
        )
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

    /// `diagonal += scale diag(K)` per axis, K frozen in `lin`: each element's rotated deviatoric block
    /// diagonal and the per-element bound of the volume term (a Jacobi preconditioner's estimate).
    pub fn add_stiffness_diagonal(
        &self,
        tets: &TetVolumes,
        lin: &FemLinearization,
        scale: f32,
        diagonal: &mut [Vec3],
    ) {
        if !self.is_on() || lin.rotations.len() != tets.len() {
            return;
        }
        let mu = self.shear_n_per_mm2;
        for (t, &tet) in tets.tets.iter().enumerate() {
            let inverse = &self.rest_inverse[t];
            let v0 = tets.rest_volume_mm3[t];
            for (k, &i) in tet.iter().enumerate() {
                let b = lin.rotations[t] * shape_gradient(inverse, k);
                let g = lin.gradients[t][k];
                let b2 = b.norm_squared();
                let d = b.map(|c| mu * v0 * (b2 + c * c / 3.0))
                    + g.map(|c| self.bulk_n_per_mm2 / v0 * c * c);
                diagonal[i as usize] += d * scale;
            }
        }
    }

    /// Gershgorin bound on node `i`'s row of the rest stiffness, N/mm (0 when off): the stability analysis.
    pub fn node_row_bound_n_per_mm(&self, i: usize) -> f32 {
        self.node_row_bound_n_per_mm.get(i).copied().unwrap_or(0.0)
    }
}

/// One element's deviatoric stiffness times its four nodes' displacements `p`: the element's part of `K p`,
/// N per node, with `inverse` its `Dm^-1`, `r` its frozen rotation and `two_mu_v0` = 2 mu V0 (N mm). The
/// local contact model ([`crate::haptics::contact_stiffness`]) applies it element by element.
#[inline(always)]
pub fn element_deviatoric_product(
    inverse: &Matrix3<f32>,
    r: &Matrix3<f32>,
    p: &[Vec3; 4],
    two_mu_v0: f32,
) -> [Vec3; 4] {
    let dp = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]) * inverse;
    let stress = deviatoric_strain_increment(&(r.transpose() * dp));
    // K p = -df: the element's force change, negated.
    let h = (r * stress * inverse.transpose()) * two_mu_v0;
    let (f1, f2, f3) = (
        h.column(0).into_owned(),
        h.column(1).into_owned(),
        h.column(2).into_owned(),
    );
    [-(f1 + f2 + f3), f1, f2, f3]
}

/// `sym(m)` with its trace removed (a strain increment: no identity to subtract).
#[inline(always)]
fn deviatoric_strain_increment(m: &Matrix3<f32>) -> Matrix3<f32> {
    let e = (m + m.transpose()) * 0.5;
    let mean = e.trace() / 3.0;
    e - Matrix3::from_diagonal_element(mean)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube of 6 tetrahedra around its main diagonal, scaled to `size` mm.
    fn cube(size: f32) -> (Vec<Vec3>, TetVolumes) {
        let x: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * size)
            .collect();
        let tets = crate::tissue::KUHN.map(|t| t.map(|i| i as u32));
        let (volumes, dropped) = TetVolumes::new(&tets, &x, 0.0);
        assert_eq!(dropped, 0);
        (x, volumes)
    }

    fn material(corotated: bool) -> FemMaterial {
        FemMaterial {
            youngs_modulus_n_per_mm2: 5e-3,
            poisson_ratio: 0.45,
            corotated,
        }
    }

    fn elements(corotated: bool) -> (Vec<Vec3>, TetVolumes, FemElements) {
        let (x, tets) = cube(3.0);
        let mut fem = FemElements::default();
        fem.refill(Some(material(corotated)), &tets, &x);
        (x, tets, fem)
    }

    #[test]
    fn rotation_of_a_rotation_is_itself_and_of_a_stretch_is_identity() {
        let q = UnitQuaternion::from_euler_angles(0.3, -1.2, 2.9);
        let r = q.to_rotation_matrix().into_inner();
        assert!((rotation_of(&r) - r).norm() < 1e-5);
        let s = Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.1);
        assert!((rotation_of(&s) - Matrix3::identity()).norm() < 1e-4);
        assert!((rotation_of(&(r * s)) - r).norm() < 1e-4);
        // Large stretch and shear on the fast path, and the same through the robust one.
        let sheared = r * Matrix3::new(1.6, 0.4, 0.0, 0.4, 0.7, 0.3, 0.0, 0.3, 1.2);
        assert!((rotation_of(&sheared) - r).norm() < 1e-4);
        assert!((rotation_of_any(&sheared) - r).norm() < 1e-4);
        // Inverted and degenerate gradients still give a rotation.
        for m in [
            Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, -1.0)),
            Matrix3::zeros(),
        ] {
            let r = rotation_of(&m);
            assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-4);
            assert!((r.determinant() - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn forces_are_minus_the_energy_gradient() {
        for corotated in [true, false] {
            let (mut x, tets, fem) = elements(corotated);
            let (mut start, mut list) = (vec![0u32], Vec::new());
            for i in 0..8u32 {
                list.extend((0..6u32).filter(|&t| tets.tets[t as usize].contains(&i)));
                start.push(list.len() as u32);
            }
            let incident = NodeTets {
                start: &start,
                tets: &list,
            };
            x[7] += Vec3::new(0.4, -0.3, 0.5);
            x[2] += Vec3::new(-0.2, 0.1, 0.3);
            let mut f = vec![Vec3::zeros(); 8];
            fem.accumulate_forces(&tets, &x, &mut f, None);
            for node in [2usize, 7] {
                let one = fem.node_force(node, &tets, incident, &x);
                assert!((one - f[node]).norm() < 1e-6, "{one} vs {}", f[node]);
                for axis in 0..3 {
                    let h = 1e-3;
                    let (mut plus, mut minus) = (x.clone(), x.clone());
                    plus[node][axis] += h;
                    minus[node][axis] -= h;
                    let numeric = -(fem.energy_n_mm(&tets, &plus) - fem.energy_n_mm(&tets, &minus))
                        / (2.0 * f64::from(h));
                    let analytic = f64::from(f[node][axis]);
                    assert!(
                        (analytic - numeric).abs() < 2e-3 * analytic.abs().max(1e-3),
                        "corotated {corotated}, node {node}, axis {axis}: {analytic} vs {numeric}"
                    );
                }
            }
            let total: Vec3 = f.iter().sum();
            assert!(total.norm() < 1e-6);
        }
    }

    #[test]
    fn a_rigid_rotation_strains_a_corotated_element_only() {
        let q = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f32::consts::FRAC_PI_2);
        for (corotated, strained) in [(true, false), (false, true)] {
            let (x, tets, fem) = elements(corotated);
            let turned: Vec<Vec3> = x.iter().map(|p| q * p).collect();
            let mut f = vec![Vec3::zeros(); 8];
            fem.accumulate_forces(&tets, &turned, &mut f, None);
            let largest = f.iter().map(|v| v.norm()).fold(0.0, f32::max);
            // Scale: E x area x unit strain on a 3 mm cube, 0.045 N.
            assert_eq!(
                largest > 1e-3,
                strained,
                "corotated {corotated}: {largest} N"
            );
        }
    }

    #[test]
    fn the_stiffness_product_matches_the_force_change() {
        let (mut x, tets, fem) = elements(true);
        x[7] += Vec3::new(0.2, -0.1, 0.3);
        let mut lin = FemLinearization::default();
        fem.linearize(&tets, &x, &mut lin);
        let p: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i as f32 * 0.7).sin(), (i as f32 * 1.3).cos(), 0.2) * 1e-3)
            .collect();
        let mut kp = vec![Vec3::zeros(); 8];
        fem.add_stiffness_product(&tets, &mut lin, &p, 1.0, &mut kp);
        let moved: Vec<Vec3> = x.iter().zip(&p).map(|(a, b)| a + b).collect();
        let (mut f0, mut f1) = (vec![Vec3::zeros(); 8], vec![Vec3::zeros(); 8]);
        fem.accumulate_forces(&tets, &x, &mut f0, None);
        fem.accumulate_forces(&tets, &moved, &mut f1, None);
        // K p ~ -(f(x + p) - f(x)), up to the rotation's change (left out of K) and second order.
        let scale = kp.iter().map(|v| v.norm()).fold(0.0, f32::max);
        for i in 0..8 {
            let df = f1[i] - f0[i];
            assert!(
                (kp[i] + df).norm() < 0.1 * scale,
                "node {i}: {} vs {}",
                kp[i],
                -df
            );
        }
    }
}

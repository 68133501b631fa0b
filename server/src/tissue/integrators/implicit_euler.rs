//! Implicit (backward) Euler, linearised once per step and solved with Jacobi-preconditioned conjugate gradient.

#![allow(clippy::needless_range_loop)] // loops walk several parallel per-node arrays by index

use super::{Integrator, fit, flush_subnormal};
use crate::tissue::fem::FemLinearization;
use crate::tissue::fem_assembly::AssembledStiffness;
use crate::tissue::springs::SpringJacobian;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// Relative residual (in the preconditioned norm) at which CG stops.
const TOLERANCE: f32 = 1e-6;

/// Solves `(M - h C - h^2 K) v1 = M v0 + h f(x0, 0)` for the new velocity (Baraff-Witkin), then
/// `x1 = x0 + h v1`. `M` is the lumped mass (kg / 1000 in these units), `K` and `C` the spring Jacobians at
/// `x0` plus the anchor and drag, `f(x0, 0)` every force except the dampers. Stable at any step for the
/// linearised system, at the price of numerical damping that grows with `h`. Finite elements enter `K` with
/// their rotations frozen at `x0` (`R K0 R^T`, the corotational stiffness) and their nodal-volume term as
/// `kappa / V0 g g^T` (Gauss-Newton), and so does the per-tetrahedron volume term. The global volume term
/// enters through `f(x0)` only (not the matrix: it couples every surface node), so a very stiff global term
/// still limits the step.
#[derive(Debug, Clone)]
pub struct ImplicitEuler {
    max_iterations: u32,
    blocks: Vec<SpringJacobian>,
    fem: FemLinearization,
    /// The elements' deviatoric stiffness assembled on the edges for this step's products.
    assembled: AssembledStiffness,
    tet_gradients: Vec<[Vec3; 4]>,
    diagonal_mass: Vec<f32>,
    rhs: Vec<Vec3>,
    residual: Vec<Vec3>,
    direction: Vec<Vec3>,
    product: Vec<Vec3>,
    preconditioned: Vec<Vec3>,
    inverse_diagonal: Vec<Vec3>,
    /// Acceleration per force of each node this step: the model's, zero on fixed and pinned rows.
    weights: Vec<f32>,
}

impl ImplicitEuler {
    /// At most `max_iterations` CG iterations per step.
    pub fn new(max_iterations: u32) -> Self {
        Self {
            max_iterations: max_iterations.max(1),
            blocks: Vec::new(),
            fem: FemLinearization::default(),
            assembled: AssembledStiffness::default(),
            tet_gradients: Vec::new(),
            diagonal_mass: Vec::new(),
            rhs: Vec::new(),
            residual: Vec::new(),
            direction: Vec::new(),
            product: Vec::new(),
            preconditioned: Vec::new(),
            inverse_diagonal: Vec::new(),
            weights: Vec::new(),
        }
    }
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

/// `out = A p`: the diagonal mass term plus the spring blocks and `h^2` times the finite elements'
/// stiffness, with fixed rows (zero `weights`) zeroed.
#[allow(clippy::too_many_arguments)] // the parts of one matrix, kept apart so each is built once per step
fn apply(
    model: &MassSpringModel,
    weights: &[f32],
    blocks: &[SpringJacobian],
    fem: &mut FemLinearization,
    assembled: &AssembledStiffness,
    tet_gradients: &[[Vec3; 4]],
    h: f32,
    diagonal_mass: &[f32],
    p: &[Vec3],
    out: &mut [Vec3],
) {
    for ((o, q), m) in out.iter_mut().zip(p).zip(diagonal_mass) {
        *o = q * *m;
    }
    model.springs().add_block_products(blocks, p, out);
    let springs = model.springs();
    if assembled.is_ready() {
        assembled.add_product(&springs.a, &springs.b, p, h * h, out);
        model
            .fem()
            .add_volume_product(model.tets(), fem, p, h * h, out);
    } else {
        model
            .fem()
            .add_stiffness_product(model.tets(), fem, p, h * h, out);
    }
    model
        .tets()
        .add_stiffness_product(tet_gradients, p, h * h, out);
    for (o, &w) in out.iter_mut().zip(weights) {
        if w == 0.0 {
            *o = Vec3::zeros();
        }
    }
}

impl Integrator for ImplicitEuler {
    fn name(&self) -> &'static str {
        "implicit-euler"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        let n = model.node_count();
        let h = dt_s;
        for buffer in [
            &mut self.rhs,
            &mut self.residual,
            &mut self.direction,
            &mut self.product,
            &mut self.preconditioned,
            &mut self.inverse_diagonal,
        ] {
            fit(buffer, n);
        }
        if self.diagonal_mass.len() != n {
            self.diagonal_mass.resize(n, 0.0);
        }
        if self.blocks.len() != model.edge_count() {
            self.blocks
                .resize(model.edge_count(), SpringJacobian::default());
        }
        model.compute_static_forces_linearized(
            &state.positions_mm,
            Some(&state.external_forces_n),
            &mut state.forces_n,
            &mut self.fem,
        );
        self.assembled.assemble(
            model.fem(),
            model.tets(),
            &self.fem,
            &model.springs().a,
            &model.springs().b,
            n,
        );
        model
            .tets()
            .gradients_into(&state.positions_mm, &mut self.tet_gradients);
        model
            .springs()
            .implicit_blocks(model.law(), &state.positions_mm, h, &mut self.blocks);

        // Fixed rows: the model's fixed nodes and the nodes a tool holds still this step.
        self.weights.clear();
        self.weights.extend_from_slice(model.accel_per_force());
        for &i in &state.pinned {
            if let Some(w) = self.weights.get_mut(i as usize) {
                *w = 0.0;
            }
        }
        let w = &self.weights[..];
        // Diagonal of A: M (1 + h drag) + h^2 k_anchor (0 on fixed rows), plus the spring blocks' diagonals.
        let (drag, k_anchor) = (model.drag_per_s(), model.anchor_stiffness_n_per_mm());
        for (m, &wi) in self.diagonal_mass.iter_mut().zip(w) {
            *m = if wi == 0.0 {
                0.0
            } else {
                (1.0 + h * drag) / wi + h * h * k_anchor
            };
        }
        for (d, m) in self.inverse_diagonal.iter_mut().zip(&self.diagonal_mass) {
            *d = Vec3::repeat(*m);
        }
        model
            .springs()
            .add_block_diagonals(&self.blocks, &mut self.inverse_diagonal);
        model
            .tets()
            .add_stiffness_diagonal(&self.tet_gradients, h * h, &mut self.inverse_diagonal);
        model.fem().add_stiffness_diagonal(
            model.tets(),
            &self.fem,
            h * h,
            &mut self.inverse_diagonal,
        );
        for (d, &wi) in self.inverse_diagonal.iter_mut().zip(w) {
            *d = if wi == 0.0 {
                Vec3::zeros()
            } else {
                d.map(|c| if c > 0.0 { 1.0 / c } else { 0.0 })
            };
        }
        // b = M v0 + h f(x0, 0) on free rows.
        for i in 0..n {
            self.rhs[i] = if w[i] == 0.0 {
                Vec3::zeros()
            } else {
                state.velocities_mm_s[i] / w[i] + state.forces_n[i] * h
            };
        }

        // Preconditioned CG from the guess v0.
        let v = &mut state.velocities_mm_s;
        apply(
            model,
            w,
            &self.blocks,
            &mut self.fem,
            &self.assembled,
            &self.tet_gradients,
            h,
            &self.diagonal_mass,
            v,
            &mut self.product,
        );
        for i in 0..n {
            self.residual[i] = self.rhs[i] - self.product[i];
            self.preconditioned[i] = self.residual[i].component_mul(&self.inverse_diagonal[i]);
        }
        self.direction.copy_from_slice(&self.preconditioned);
        let mut rho = dot(&self.residual, &self.preconditioned);
        let threshold = TOLERANCE * TOLERANCE * dot(&self.rhs, &self.rhs).max(1e-30);
        let mut iterations = 0;
        while iterations < self.max_iterations && dot(&self.residual, &self.residual) > threshold {
            iterations += 1;
            apply(
                model,
                w,
                &self.blocks,
                &mut self.fem,
                &self.assembled,
                &self.tet_gradients,
                h,
                &self.diagonal_mass,
                &self.direction,
                &mut self.product,
            );
            let curvature = dot(&self.direction, &self.product);
            if curvature.is_nan() || curvature <= 0.0 {
                break;
            }
            let alpha = rho / curvature;
            for i in 0..n {
                v[i] += self.direction[i] * alpha;
                self.residual[i] -= self.product[i] * alpha;
                self.preconditioned[i] = self.residual[i].component_mul(&self.inverse_diagonal[i]);
            }
            let rho_next = dot(&self.residual, &self.preconditioned);
            let beta = rho_next / rho;
            rho = rho_next;
            for (d, z) in self.direction.iter_mut().zip(&self.preconditioned) {
                *d = z + *d * beta;
            }
        }
        for (i, &wi) in w.iter().enumerate() {
            if wi == 0.0 {
                v[i] = Vec3::zeros();
                continue;
            }
            v[i] = flush_subnormal(v[i]);
            state.positions_mm[i] = flush_subnormal(state.positions_mm[i] + v[i] * h);
        }
        iterations
    }
}

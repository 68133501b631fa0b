//! XPBD: extended position-based dynamics with distance and volume constraints.
//!
//! Each spring is a distance constraint with compliance `1 / k` (its tangent stiffness), each tetrahedron and
//! the global volume a volume constraint with compliance `V0 / K`. Springs are edge-coloured once per model:
//! inside one colour no two springs share a node, so a colour is swept in blocks with no write conflicts and
//! the sweep order walks memory in index order within each colour.

#![allow(clippy::needless_range_loop)] // loops walk several parallel per-node arrays by index

use super::{Integrator, fit, flush_subnormal};
use crate::tissue::springs::SpringSet;
use crate::tissue::volume::{tet_volume_gradients, tet_volume_mm3};
use crate::tissue::{MM_PER_M, MassSpringModel, TissueState, Vec3};

/// Springs of one model reordered by colour, with the colour boundaries.
#[derive(Debug, Clone, Default)]
struct ColouredSprings {
    /// Which model ([`MassSpringModel::id`]) this was built for; 0 before the first build (ids start at 1).
    key: u64,
    springs: SpringSet,
    colour_start: Vec<usize>,
    /// Build scratch, kept so a rebuild for a new model of no larger size allocates nothing.
    used: Vec<u128>,
    colour_of: Vec<usize>,
    order: Vec<usize>,
}

/// The colouring cache key. Regression guard: the key was (spring count, first a, last b, node count), and two
/// region sub-models of the same size and ends shared one colouring; the model's unique id cannot collide.
fn model_key(model: &MassSpringModel) -> u64 {
    model.id()
}

impl ColouredSprings {
    /// Greedy edge colouring: each spring takes the lowest colour neither endpoint uses yet; springs are then
    /// reordered by colour (index order within a colour). Reuses this value's buffers.
    fn rebuild(&mut self, model: &MassSpringModel) {
        let springs = model.springs();
        self.used.clear();
        self.used.resize(model.node_count(), 0);
        self.colour_of.clear();
        let mut colours = 0usize;
        for s in 0..springs.len() {
            let (a, b) = (springs.a[s] as usize, springs.b[s] as usize);
            let free = !(self.used[a] | self.used[b]);
            // 128 colours exceed any mesh of degree < 64; beyond that, share the last colour (still correct
            // as Gauss-Seidel, just not conflict-free).
            let colour = (free.trailing_zeros() as usize).min(127);
            self.used[a] |= 1 << colour;
            self.used[b] |= 1 << colour;
            self.colour_of.push(colour);
            colours = colours.max(colour + 1);
        }
        self.order.clear();
        self.order.extend(0..springs.len());
        let colour_of = &self.colour_of;
        self.order.sort_unstable_by_key(|&s| (colour_of[s], s));
        self.springs.clear();
        self.colour_start.clear();
        self.colour_start.resize(colours + 1, 0);
        for &s in &self.order {
            let (a, b, rest, k, c) = springs.get(s);
            self.springs.push(a as u32, b as u32, rest, k, c);
            self.colour_start[colour_of[s] + 1] += 1;
        }
        for c in 0..colours {
            self.colour_start[c + 1] += self.colour_start[c];
        }
        self.key = model_key(model);
    }
}

/// XPBD with `iterations` constraint sweeps per step. Unconditionally stable; stiffness is reached only as
/// the sweeps converge (few sweeps make a softer material), which is the method's trade.
#[derive(Debug, Clone)]
pub struct Xpbd {
    iterations: u32,
    coloured: ColouredSprings,
    lambda_springs: Vec<f32>,
    lambda_tets: Vec<f32>,
    previous: Vec<Vec3>,
    gradient: Vec<Vec3>,
}

impl Xpbd {
    /// `iterations` sweeps per step (at least 1).
    pub fn new(iterations: u32) -> Self {
        Self {
            iterations: iterations.max(1),
            coloured: ColouredSprings::default(),
            lambda_springs: Vec::new(),
            lambda_tets: Vec::new(),
            previous: Vec::new(),
            gradient: Vec::new(),
        }
    }

    /// Number of colours of the current model (after a step).
    pub fn colours(&self) -> usize {
        self.coloured.colour_start.len().saturating_sub(1)
    }
}

impl Integrator for Xpbd {
    fn name(&self) -> &'static str {
        "xpbd"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        let n = model.node_count();
        if self.coloured.key != model_key(model) || self.coloured.colour_start.is_empty() {
            self.coloured.rebuild(model);
        }
        fit(&mut self.previous, n);
        fit(&mut self.gradient, n);
        self.lambda_springs.clear();
        self.lambda_springs.resize(model.edge_count(), 0.0);
        self.lambda_tets.clear();
        self.lambda_tets.resize(model.tets().len(), 0.0);
        let h = dt_s;
        let inv_h2 = 1.0 / (h * h);
        let w = model.accel_per_force();

        // Predict with the forces that are not constraints: anchors, gravity, external; drag implicitly.
        let k_anchor = model.anchor_stiffness_n_per_mm();
        let g = model.gravity_mm_per_s2() / MM_PER_M;
        let drag_factor = 1.0 / (1.0 + h * model.drag_per_s());
        for i in 0..n {
            self.previous[i] = state.positions_mm[i];
            if w[i] == 0.0 {
                continue;
            }
            let x = state.positions_mm[i];
            let f = (model.rest_positions_mm()[i] - x) * k_anchor
                + g * model.mass_kg()[i]
                + state.external_forces_n[i];
            // Drag acts on the velocity carried over, not on this step's force impulse: damping the impulse
            // would bias the rest state (a chain under gravity sagged by 1 / (1 + h drag) too little).
            state.velocities_mm_s[i] = state.velocities_mm_s[i] * drag_factor + f * (w[i] * h);
            state.positions_mm[i] = x + state.velocities_mm_s[i] * h;
        }

        let law = model.law();
        let springs = &self.coloured.springs;
        let p = &mut state.positions_mm;
        for _ in 0..self.iterations {
            for c in 0..self.coloured.colour_start.len() - 1 {
                for s in self.coloured.colour_start[c]..self.coloured.colour_start[c + 1] {
                    let (a, b, rest, k, damping) = springs.get(s);
                    let (wa, wb) = (w[a], w[b]);
                    let w_sum = wa + wb;
                    if w_sum == 0.0 {
                        continue;
                    }
                    let d = p[b] - p[a];
                    let len = d.norm();
                    if len <= 1e-9 {
                        continue;
                    }
                    let n_ab = d / len;
                    let stretch = len - rest;
                    let kt = law.tangent_n_per_mm(stretch, rest, k);
                    // Effective constraint: the stretch a linear spring of stiffness kt would need for this
                    // tension (equals the stretch for the linear law).
                    let constraint = law.tension_n(stretch, rest, k) / kt;
                    let alpha = inv_h2 / kt;
                    // XPBD damping: gamma = alpha_tilde * beta_tilde / h with beta_tilde = h^2 c.
                    let gamma = alpha * damping * h;
                    let rate = n_ab.dot(&((p[b] - self.previous[b]) - (p[a] - self.previous[a])));
                    let lambda = &mut self.lambda_springs[s];
                    let delta = (-constraint - alpha * *lambda - gamma * rate)
                        / ((1.0 + gamma) * w_sum + alpha);
                    *lambda += delta;
                    p[a] -= n_ab * (wa * delta);
                    p[b] += n_ab * (wb * delta);
                }
            }
            let tets = model.tets();
            if tets.bulk_modulus_n_per_mm2 > 0.0 {
                for t in 0..tets.len() {
                    let tet = tets.tets[t];
                    let v0 = tets.rest_volume_mm3[t];
                    let constraint = tet_volume_mm3(p, tet) - v0;
                    let grads = tet_volume_gradients(p, tet);
                    let alpha = v0 / tets.bulk_modulus_n_per_mm2 * inv_h2;
                    let mut denominator = alpha;
                    for (k, &v) in tet.iter().enumerate() {
                        denominator += w[v as usize] * grads[k].norm_squared();
                    }
                    if denominator <= 0.0 {
                        continue;
                    }
                    let lambda = &mut self.lambda_tets[t];
                    let delta = (-constraint - alpha * *lambda) / denominator;
                    *lambda += delta;
                    for (k, &v) in tet.iter().enumerate() {
                        p[v as usize] += grads[k] * (w[v as usize] * delta);
                    }
                }
            }
            if let Some(global) = model.global_volume() {
                // One constraint on the enclosed volume, gradient over every surface vertex.
                let triangles = model.triangles();
                self.gradient.fill(Vec3::zeros());
                let mut six_v = 0.0;
                for tri in triangles {
                    let [a, b, c] = tri.map(|i| p[i as usize]);
                    six_v += a.dot(&b.cross(&c));
                    self.gradient[tri[0] as usize] += b.cross(&c) / 6.0;
                    self.gradient[tri[1] as usize] += c.cross(&a) / 6.0;
                    self.gradient[tri[2] as usize] += a.cross(&b) / 6.0;
                }
                let constraint = six_v / 6.0 - global.rest_volume_mm3;
                let alpha = global.rest_volume_mm3 / global.bulk_modulus_n_per_mm2 * inv_h2;
                let denominator = alpha
                    + self
                        .gradient
                        .iter()
                        .zip(w)
                        .map(|(g, wi)| wi * g.norm_squared())
                        .sum::<f32>();
                if denominator > 0.0 {
                    // lambda restarts each sweep: one global constraint converges in a sweep or two.
                    let delta = -constraint / denominator;
                    for ((x, g), wi) in p.iter_mut().zip(&self.gradient).zip(w) {
                        *x += g * (wi * delta);
                    }
                }
            }
        }
        let inv_h = 1.0 / h;
        for i in 0..n {
            if w[i] == 0.0 {
                continue;
            }
            state.velocities_mm_s[i] = flush_subnormal((p[i] - self.previous[i]) * inv_h);
            p[i] = flush_subnormal(p[i]);
        }
        self.iterations
    }
}

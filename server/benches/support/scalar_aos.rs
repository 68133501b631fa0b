//! The baseline the integrators bench measures beside our kernels in the same run: a symplectic-Euler step
//! written the way the 2001 framework would have written it. Nodes and springs are arrays of structs of
//! three-float vectors; one pass accumulates each spring's Hooke and edge-damping force into both nodes, one
//! pass adds anchors and drag and integrates. Same model, same physics, no layout work: the ratio of our step
//! to this one travels between machines where absolute microseconds do not.

use sinew_server::tissue::{MassSpringModel, TissueState};

#[derive(Clone, Copy)]
struct Node {
    x: [f32; 3],
    v: [f32; 3],
    f: [f32; 3],
    rest: [f32; 3],
    inv_mass: f32,
    fixed: bool,
}

#[derive(Clone, Copy)]
struct Spring {
    a: u32,
    b: u32,
    rest: f32,
    k: f32,
    c: f32,
}

/// The pad as arrays of structs.
pub struct ScalarPad {
    nodes: Vec<Node>,
    springs: Vec<Spring>,
    anchor_k: f32,
    drag: f32,
}

impl ScalarPad {
    /// Copy `model` in the state `state`.
    pub fn new(model: &MassSpringModel, state: &TissueState) -> Self {
        let nodes = (0..model.node_count())
            .map(|i| Node {
                x: state.positions_mm[i].into(),
                v: state.velocities_mm_s[i].into(),
                f: [0.0; 3],
                rest: model.rest_positions_mm()[i].into(),
                inv_mass: model.accel_per_force()[i],
                fixed: model.is_fixed(i),
            })
            .collect();
        let s = model.springs();
        let springs = (0..s.a.len())
            .map(|k| Spring {
                a: s.a[k],
                b: s.b[k],
                rest: s.rest_mm[k],
                k: s.stiffness_n_per_mm[k],
                c: s.damping_n_s_per_mm[k],
            })
            .collect();
        Self {
            nodes,
            springs,
            anchor_k: model.anchor_stiffness_n_per_mm(),
            drag: model.drag_per_s(),
        }
    }

    /// One symplectic-Euler step of `dt_s`.
    #[allow(clippy::needless_range_loop)] // written as the 2001 code would be: indexed three-float loops
    pub fn step(&mut self, dt_s: f32) {
        for n in &mut self.nodes {
            n.f = [0.0; 3];
        }
        for s in &self.springs {
            let (a, b) = (self.nodes[s.a as usize], self.nodes[s.b as usize]);
            let d = [b.x[0] - a.x[0], b.x[1] - a.x[1], b.x[2] - a.x[2]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            let u = [d[0] / len, d[1] / len, d[2] / len];
            let dv = [b.v[0] - a.v[0], b.v[1] - a.v[1], b.v[2] - a.v[2]];
            let along = dv[0] * u[0] + dv[1] * u[1] + dv[2] * u[2];
            let t = s.k * (len - s.rest) + s.c * along;
            for axis in 0..3 {
                self.nodes[s.a as usize].f[axis] += t * u[axis];
                self.nodes[s.b as usize].f[axis] -= t * u[axis];
            }
        }
        let (anchor_k, drag) = (self.anchor_k, self.drag);
        for n in &mut self.nodes {
            if n.fixed {
                continue;
            }
            for axis in 0..3 {
                let f = n.f[axis] - anchor_k * (n.x[axis] - n.rest[axis]);
                n.v[axis] += dt_s * (f * n.inv_mass - drag * n.v[axis]);
                n.x[axis] += dt_s * n.v[axis];
            }
        }
    }

    /// Every coordinate finite.
    pub fn is_finite(&self) -> bool {
        self.nodes
            .iter()
            .all(|n| n.x.iter().chain(&n.v).all(|c| c.is_finite()))
    }
}

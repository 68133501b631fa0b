//! A suture thread's chain of segments, held to length by a direct solve: the core of the thread's dynamics.
//!
//! Owns: [`ThreadChain`] (node positions and velocities, inverse masses, the nodes' material coordinates and the
//! segments' rest lengths between them, the solver's scratch) and its step, and [`NodeHold`] (a node held for
//! one step by implicit springs inside the solve: a hole around it). A node the thread slides through
//! ([`ThreadChain::slide_node`], [`NodeSlide`]) has its material coordinate solved with the positions; a hole
//! takes a node ([`ThreadChain::place_node_at`]) and hands it on as the thread runs
//! ([`ThreadChain::hand_across`]). Bending, collisions and holes build on it (`docs/suturing.md`, "Thread").
//!
//! Why a direct solve. A segment's distance constraint couples only its two nodes, so the chain's linearised
//! constraint system is tridiagonal: `(J W J^T + alpha / h^2) dlambda = -C - alpha lambda / h^2`, with
//! `diag_i = w_i + w_{i+1} + alpha_i / h^2` and `off_i = -w_{i+1} (n_i . n_{i+1})` (`n_i` the unit direction of
//! segment `i`, `w` the inverse masses). The Thomas algorithm solves it exactly in O(n), so one Newton step a
//! substep holds every segment to its compliance's strain however hard the ends are pulled; a Gauss-Seidel
//! sweep (the XPBD integrator's) carries a correction one segment along, and a 64-segment chain pulled with 5 N
//! stretched 7.7% under it at 64 substeps a tick (Deul et al. 2018 make the same case for stiff rods).
//!
//! Must not: allocate once built, or panic on any state (a non-finite step leaves the chain as it was).

use super::thread_solve::{ChainTerms, NodeSlide, PositionSolve, V64};
use crate::tissue::{MM_PER_M, Vec3};

/// A chain of `n` nodes and `n - 1` segments.
#[derive(Debug, Clone)]
pub struct ThreadChain {
    /// Node positions, mm.
    pub positions_mm: Vec<Vec3>,
    /// Node velocities, mm/s.
    pub velocities_mm_s: Vec<Vec3>,
    /// External forces on the nodes this step, N (cleared by the caller).
    pub forces_n: Vec<Vec3>,
    /// Inverse masses, 1/kg (0: the node is held where it is, e.g. on the needle's tail).
    inverse_mass_per_kg: Vec<f32>,
    rest_mm: Vec<f32>,
    /// Each node's material coordinate: the rest length from node 0 to it, mm (the prefix sums of `rest_mm`), and
    /// in f64 (the solve's).
    node_u_mm: Vec<f32>,
    u64: Vec<f64>,
    /// Axial rigidity EA, N (a segment's spring is `EA / l`).
    axial_rigidity_n: f32,
    /// Viscous drag on every node, 1/s.
    drag_per_s: f32,
    /// Each segment's tension at the last step, N.
    tension_n: Vec<f32>,
    /// Bending stiffness of each hinge, N/mm (0: a rope; [`ThreadChain::set_bending`]).
    bend_stiffness_n_per_mm: f32,
    /// The positions before the step (f32, as the caller sees them).
    previous_mm: Vec<Vec3>,
    /// Each segment's spring, N/mm (`EA / l`).
    stiffness_n_per_mm: Vec<f32>,
    // The positions in f64 (the solve's; `positions_mm` is their f32 copy, and a change the caller makes to
    // that copy is taken in), before the step, predicted, and the f32 copy as last written.
    x64: Vec<V64>,
    prev64: Vec<V64>,
    predicted64: Vec<V64>,
    mirror_mm: Vec<Vec3>,
    solver: PositionSolve,
    /// This step's holds ([`ThreadChain::hold_node`]) and slides ([`ThreadChain::slide_node`]), per node.
    hold: Vec<Option<NodeHold>>,
    slides: Vec<Option<NodeSlide>>,
}

/// How a node is held for one step ([`ThreadChain::hold_node`]): a hole in the tissue around it, springs
/// toward a place, one across a direction and one along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeHold {
    /// The thread's direction through the hole (unit).
    pub direction: Vec3,
    /// Where the springs pull the node, mm.
    pub place_mm: Vec3,
    /// The spring across the direction, N/mm (the tissue's stiffness against the point; more than 0).
    pub across_n_per_mm: f32,
    /// The spring along it, N/mm (0: free along; a hole holds its node the same every way).
    pub along_n_per_mm: f32,
}

impl ThreadChain {
    /// A chain through `nodes_mm` (at least two, segments at rest as given), `node_mass_kg` a node, axial
    /// rigidity `axial_rigidity_n` (a segment of rest length `l` stretches `F l / EA` under `F`), drag
    /// `drag_per_s`. None for fewer than two nodes, a zero-length segment or a non-positive mass or rigidity.
    pub fn new(
        nodes_mm: &[Vec3],
        node_mass_kg: f32,
        axial_rigidity_n: f32,
        drag_per_s: f32,
    ) -> Option<Self> {
        let n = nodes_mm.len();
        if n < 2 || !(node_mass_kg > 0.0 && axial_rigidity_n > 0.0 && drag_per_s >= 0.0) {
            return None;
        }
        let rest_mm: Vec<f32> = nodes_mm.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
        if rest_mm.iter().any(|l| !(l.is_finite() && *l > 1e-6)) {
            return None;
        }
        let m = n - 1;
        let node_u_mm: Vec<f32> = std::iter::once(0.0)
            .chain(rest_mm.iter().scan(0.0, |u, l| {
                *u += l;
                Some(*u)
            }))
            .collect();
        Some(Self {
            positions_mm: nodes_mm.to_vec(),
            velocities_mm_s: vec![Vec3::zeros(); n],
            forces_n: vec![Vec3::zeros(); n],
            inverse_mass_per_kg: vec![1.0 / node_mass_kg; n],
            drag_per_s,
            tension_n: vec![0.0; m],
            bend_stiffness_n_per_mm: 0.0,
            previous_mm: vec![Vec3::zeros(); n],
            stiffness_n_per_mm: rest_mm.iter().map(|l| axial_rigidity_n / l).collect(),
            u64: node_u_mm.iter().map(|&u| f64::from(u)).collect(),
            node_u_mm,
            axial_rigidity_n,
            rest_mm,
            x64: nodes_mm.iter().map(|p| p.cast::<f64>()).collect(),
            prev64: vec![V64::zeros(); n],
            predicted64: vec![V64::zeros(); n],
            mirror_mm: nodes_mm.to_vec(),
            solver: PositionSolve::new(n),
            hold: vec![None; n],
            slides: vec![None; n],
        })
    }

    /// Hold node `i` where it is (it moves only when the caller moves it: a needle's tail, a grasper's jaws),
    /// or give it mass `node_mass_kg` again.
    pub fn set_held(&mut self, i: usize, held: bool, node_mass_kg: f32) {
        if let Some(w) = self.inverse_mass_per_kg.get_mut(i) {
            *w = if held || node_mass_kg.is_nan() || node_mass_kg <= 0.0 {
                0.0
            } else {
                1.0 / node_mass_kg
            };
        }
    }

    /// Hold node `i` for the next step only (a hole around it): springs toward a place, implicit, one across
    /// a direction and one along it ([`NodeHold`]). For a spring `k` the node's inverse mass that way becomes
    /// `w / (1 + w h^2 k)` and its prediction is drawn toward the place by `w h^2 k / (1 + w h^2 k)` of the
    /// way; the direct solve sees both, so the tensions either side of a held node are the thread's real pull
    /// against the tissue (a light node moved after the solve would show only its own inertia). False
    /// (nothing held) for a held node, a bad index or a non-finite hold.
    pub fn hold_node(&mut self, i: usize, hold: NodeHold) -> bool {
        let Some(&w) = self.inverse_mass_per_kg.get(i) else {
            return false;
        };
        let Some(direction) = hold.direction.try_normalize(1e-6) else {
            return false;
        };
        let finite = hold
            .place_mm
            .iter()
            .chain(direction.iter())
            .all(|c| c.is_finite());
        let across_ok = hold.across_n_per_mm > 0.0 && hold.across_n_per_mm.is_finite();
        let along_ok = hold.along_n_per_mm >= 0.0 && hold.along_n_per_mm.is_finite();
        let usable = w != 0.0 && finite && across_ok && along_ok;
        if !usable {
            return false;
        }
        self.hold[i] = Some(NodeHold { direction, ..hold });
        true
    }

    /// Resist bending with a flexural rigidity `ei_n_mm2` (N mm^2; 0 or less: none). Each interior node's
    /// offset from its neighbours' midpoint, `C = x_i - (x_{i-1} + x_{i+1}) / 2`, is `l theta / 2` for a hinge
    /// bent by `theta` between segments of length `l`, so an energy `EI theta^2 / (2 l)` is `k |C|^2 / 2` with
    /// `k = 4 EI / l^3` (taken at the mean segment length).
    pub fn set_bending(&mut self, ei_n_mm2: f32) {
        let l = self.rest_length_mm() / self.rest_mm.len() as f32;
        let k = 4.0 * ei_n_mm2 / (l * l * l);
        self.bend_stiffness_n_per_mm = if k.is_finite() && k > 0.0 { k } else { 0.0 };
    }

    /// Where the nodes were before the current step's motion (the start of the last step), mm.
    pub fn previous_mm(&self) -> &[Vec3] {
        &self.previous_mm
    }

    /// The inverse mass of each node, 1/kg (0: held).
    pub fn inverse_mass_per_kg(&self) -> &[f32] {
        &self.inverse_mass_per_kg
    }

    /// Each segment's tension at the last step, N (its XPBD multiplier over the step squared).
    pub fn tension_n(&self) -> &[f32] {
        &self.tension_n
    }

    /// Each segment's spring, N/mm (`EA / l`).
    pub fn stiffness_n_per_mm(&self) -> &[f32] {
        &self.stiffness_n_per_mm
    }

    /// The chain's length now, mm.
    pub fn length_mm(&self) -> f32 {
        self.positions_mm
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum()
    }

    /// The chain's rest length, mm.
    pub fn rest_length_mm(&self) -> f32 {
        self.rest_mm.iter().sum()
    }

    /// Each segment's rest length, mm (they change as the thread slides through a hole: [`ThreadChain::slide`]).
    pub fn rest_mm(&self) -> &[f32] {
        &self.rest_mm
    }

    /// Each node's material coordinate: the rest length from node 0 to it, mm.
    pub fn node_u_mm(&self) -> &[f32] {
        &self.node_u_mm
    }

    /// Let the material slide through interior node `i` for the next step only ([`NodeSlide`]: its material
    /// coordinate a variable of the solve, `thread_solve.rs`); the segments either side take and give rest
    /// length as it moves, their springs following after the step. False (nothing taken) for an end node, a
    /// held one, or a non-finite or empty range.
    pub fn slide_node(&mut self, i: usize, slide: NodeSlide) -> bool {
        let usable = i > 0
            && i + 1 < self.positions_mm.len()
            && self.inverse_mass_per_kg[i] != 0.0
            && slide.predicted_u_mm.is_finite()
            && slide.friction_n.is_finite()
            && slide.tangent.iter().all(|c| c.is_finite())
            && slide.lo_mm <= slide.hi_mm
            && slide.lo_mm > self.u64[i - 1]
            && slide.hi_mm < self.u64[i + 1];
        if usable {
            self.slides[i] = Some(slide);
        }
        usable
    }

    /// Hand interior node `to` (a neighbour of interior node `from`) the place, motion and material coordinate
    /// of `from`, and make `from` a node halfway along the material between that coordinate and the node beyond
    /// `from` (placed and moving halfway between the two): a sliding node passing a free one, as the thread
    /// runs through its hole, so no segment shrinks to nothing (`thread_hole.rs`). False (nothing changed)
    /// for nodes that are not neighbours, an end node, or `to` held.
    pub fn hand_across(&mut self, from: usize, to: usize) -> bool {
        let n = self.positions_mm.len();
        let interior = |i: usize| i > 0 && i + 1 < n;
        if !(interior(from) && interior(to) && from.abs_diff(to) == 1)
            || self.inverse_mass_per_kg[to] == 0.0
        {
            return false;
        }
        let beyond = if to < from { from + 1 } else { from - 1 };
        let (u_from, u_beyond) = (self.u64[from], self.u64[beyond]);
        self.x64[to] = self.x64[from];
        self.velocities_mm_s[to] = self.velocities_mm_s[from];
        self.set_u(to, u_from);
        self.x64[from] = (self.x64[from] + self.x64[beyond]) * 0.5;
        self.velocities_mm_s[from] =
            (self.velocities_mm_s[from] + self.velocities_mm_s[beyond]) * 0.5;
        self.set_u(from, 0.5 * (u_from + u_beyond));
        for i in [to, from] {
            self.positions_mm[i] = self.x64[i].cast::<f32>();
            self.mirror_mm[i] = self.positions_mm[i];
        }
        // The segments touching the two nodes.
        let (lo, hi) = (from.min(to), from.max(to));
        self.segments_changed(lo - 1, hi);
        true
    }

    /// Move node `i`'s material coordinate to `u_mm` (kept `min_mm` from its neighbours') and the node to the
    /// point of the chain at that coordinate as it lies: a hole taking the thread at `u_mm` makes that node its
    /// own (`thread_hole.rs`). Returns the coordinate taken (None for an end node or a non-finite input).
    pub fn place_node_at(&mut self, i: usize, u_mm: f32, min_mm: f32) -> Option<f32> {
        let n = self.positions_mm.len();
        if i == 0 || i + 1 >= n || !u_mm.is_finite() {
            return None;
        }
        let min_mm = f64::from(min_mm);
        let (lo, hi) = (self.u64[i - 1] + min_mm, self.u64[i + 1] - min_mm);
        if lo > hi {
            return None;
        }
        let u = f64::from(u_mm).clamp(lo, hi);
        // The point at u on the segment either side of node i, by the rest lengths as they are.
        let (a, b, t) = if u <= self.u64[i] {
            (
                i - 1,
                i,
                (u - self.u64[i - 1]) / (self.u64[i] - self.u64[i - 1]),
            )
        } else {
            (
                i,
                i + 1,
                (u - self.u64[i]) / (self.u64[i + 1] - self.u64[i]),
            )
        };
        let t = t.clamp(0.0, 1.0);
        self.x64[i] = self.x64[a] + (self.x64[b] - self.x64[a]) * t;
        self.velocities_mm_s[i] = self.velocities_mm_s[a]
            + (self.velocities_mm_s[b] - self.velocities_mm_s[a]) * t as f32;
        self.positions_mm[i] = self.x64[i].cast::<f32>();
        self.mirror_mm[i] = self.positions_mm[i];
        self.set_u(i, u);
        self.segments_changed(i - 1, i);
        Some(u as f32)
    }

    /// Node `i`'s material coordinate becomes `u_mm` (the rest lengths then follow: `segments_changed`).
    fn set_u(&mut self, i: usize, u_mm: f64) {
        self.u64[i] = u_mm;
        self.node_u_mm[i] = u_mm as f32;
    }

    /// The material coordinates of the nodes of segments `first..=last` changed: their rest lengths, springs and
    /// tensions follow.
    fn segments_changed(&mut self, first: usize, last: usize) {
        for s in first..=last.min(self.rest_mm.len() - 1) {
            let l = (self.u64[s + 1] - self.u64[s]) as f32;
            self.rest_mm[s] = l;
            self.stiffness_n_per_mm[s] = self.axial_rigidity_n / l;
            let stretch = (self.x64[s + 1] - self.x64[s]).norm() - f64::from(l);
            self.tension_n[s] = (stretch * f64::from(self.stiffness_n_per_mm[s])) as f32;
        }
    }

    /// One step of `h_s` under gravity `gravity_mm_per_s2` and `forces_n`: predict, then `newton` direct solves
    /// of the segments' constraints, then velocities from the motion. A step that would leave a non-finite
    /// value leaves the chain as it was. No allocation.
    pub fn step(&mut self, h_s: f32, gravity_mm_per_s2: &Vec3, newton: usize) {
        self.step_with(h_s, gravity_mm_per_s2, newton, |_, _, _| {});
    }

    /// [`ThreadChain::step`], with the bending pass (if any) before the length solve, and `constrain` run
    /// after it on (the positions at the step's start, the positions now, the inverse masses): contacts put
    /// nodes back where they may be, and the velocities then follow from the corrected motion.
    pub fn step_with(
        &mut self,
        h_s: f32,
        gravity_mm_per_s2: &Vec3,
        newton: usize,
        mut constrain: impl FnMut(&[Vec3], &mut [Vec3], &[f32]),
    ) {
        let n = self.positions_mm.len();
        if !(h_s > 0.0 && h_s.is_finite()) {
            self.clear_holds();
            return;
        }
        let h = f64::from(h_s);
        let drag = 1.0 / (1.0 + h_s * self.drag_per_s);
        for i in 0..n {
            // A position the caller set since the last step (the tail, the jaws, a lay-out) is taken as given.
            if self.positions_mm[i] != self.mirror_mm[i] {
                self.x64[i] = self.positions_mm[i].cast::<f64>();
            }
            self.previous_mm[i] = self.positions_mm[i];
            self.prev64[i] = self.x64[i];
            let w = self.inverse_mass_per_kg[i];
            if w == 0.0 {
                self.velocities_mm_s[i] = Vec3::zeros();
                self.predicted64[i] = self.x64[i];
                continue;
            }
            // a = F / m in mm/s^2: N/kg is m/s^2.
            let accel = gravity_mm_per_s2 + self.forces_n[i] * (w * MM_PER_M);
            self.velocities_mm_s[i] = self.velocities_mm_s[i] * drag + accel * h_s;
            self.predicted64[i] = self.x64[i] + self.velocities_mm_s[i].cast::<f64>() * h;
        }
        let terms = ChainTerms {
            inverse_mass_per_kg: &self.inverse_mass_per_kg,
            holds: &self.hold,
            slides: &self.slides,
            stiffness_n_per_mm: &self.stiffness_n_per_mm,
            bend_n_per_mm: self.bend_stiffness_n_per_mm,
        };
        self.solver.solve(
            &mut self.x64,
            &mut self.u64,
            &self.predicted64,
            &terms,
            h,
            newton.max(1),
        );
        // The material coordinates the slides moved, and the rest lengths and springs with them.
        for i in 0..n {
            if self.slides[i].is_some() {
                if self.u64[i].is_finite() {
                    self.set_u(i, self.u64[i]);
                    self.segments_changed(i - 1, i);
                } else {
                    self.u64[i] = f64::from(self.node_u_mm[i]);
                }
            }
        }
        self.clear_holds();
        // The tension each segment's stretch carries, as the solve left it (the contacts after it move nodes
        // without a force).
        for s in 0..self.rest_mm.len() {
            let stretch = (self.x64[s + 1] - self.x64[s]).norm() - f64::from(self.rest_mm[s]);
            self.tension_n[s] = (stretch * f64::from(self.stiffness_n_per_mm[s])) as f32;
        }
        for i in 0..n {
            self.positions_mm[i] = self.x64[i].cast::<f32>();
            self.mirror_mm[i] = self.positions_mm[i];
        }
        constrain(
            &self.previous_mm,
            &mut self.positions_mm,
            &self.inverse_mass_per_kg,
        );
        let finite = self
            .positions_mm
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite()))
            && self.x64.iter().all(|p| p.iter().all(|c| c.is_finite()));
        if !finite {
            self.positions_mm.copy_from_slice(&self.previous_mm);
            self.mirror_mm.copy_from_slice(&self.previous_mm);
            self.x64.copy_from_slice(&self.prev64);
            self.velocities_mm_s.fill(Vec3::zeros());
            self.tension_n.fill(0.0);
            return;
        }
        for i in 0..n {
            // The contacts' moves, taken in as differences: a node they leave alone keeps its f64 place.
            if self.positions_mm[i] != self.mirror_mm[i] {
                self.x64[i] += (self.positions_mm[i] - self.mirror_mm[i]).cast::<f64>();
                self.mirror_mm[i] = self.positions_mm[i];
            }
            self.velocities_mm_s[i] = ((self.x64[i] - self.prev64[i]) / h).cast::<f32>();
        }
    }

    /// Every node free again (holds and slides last one step).
    fn clear_holds(&mut self) {
        self.hold.fill(None);
        self.slides.fill(None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_64_segment_thread_holding_a_5_n_weight_stretches_half_a_percent_and_carries_5_n() {
        // 64 segments of 2 mm hanging down from a held top node, 2e-6 kg a node, EA 1000 N (0.5% under 5 N),
        // a 0.51 kg weight (5 N) on the bottom node: a light chain and a heavy end, the case a Gauss-Seidel
        // sweep cannot carry.
        let nodes: Vec<Vec3> = (0..=64)
            .map(|i| Vec3::new(0.0, 0.0, -2.0 * i as f32))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-6, 1000.0, 20.0).unwrap();
        chain.set_held(0, true, 2e-6);
        chain.set_held(64, false, 5.0 / 9.81);
        let g = Vec3::new(0.0, 0.0, -9810.0);
        let mut longest = 0.0f32;
        for tick in 0..2000 {
            for _ in 0..4 {
                chain.step(0.00025, &g, 2);
            }
            if tick >= 1000 {
                longest = longest.max(chain.length_mm());
            }
        }
        let tension = chain.tension_n();
        println!(
            "longest {longest:.3} mm of {:.1}; tension at the top {:.3} N, at the weight {:.3} N",
            chain.rest_length_mm(),
            tension[0],
            tension[63]
        );
        assert!(longest <= 128.0 * 1.01, "{longest} mm: more than 1%");
        assert!(
            longest >= 128.0 * 1.002,
            "{longest} mm: the weight never hung on it"
        );
        for t in [tension[0], tension[63]] {
            assert!(
                (t - 5.0).abs() < 0.25,
                "tension {t} N, not the weight's 5 N"
            );
        }
        assert!(
            chain
                .positions_mm
                .iter()
                .all(|p| p.iter().all(|c| c.is_finite()))
        );
    }

    #[test]
    fn a_thread_drawn_taut_between_two_held_nodes_stretches_straight_and_reads_ea_times_its_strain()
    {
        // The suture thread's constants (thread.rs): 150 mm in 64 segments, 0.1 mg/mm, EA 1000 N, EI 0.5 N mm2.
        // It hangs from node 0; node 10 is then held, carried 10 mm up and aside (the ten segments between go
        // slack) and drawn down until the two held nodes are 16% further apart than those segments are long.
        // A converged solve leaves them straight, each stretched
        // alike, carrying EA times the strain; the old multiplier solve left a zigzag reading 0.05 N of 200.
        let segment_mm = 150.0 / 64.0;
        let nodes: Vec<Vec3> = (0..=64)
            .map(|i| Vec3::new(0.0, 0.0, -segment_mm * i as f32))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 1e-7 * segment_mm, 1000.0, 5.0).unwrap();
        chain.set_held(0, true, 0.0);
        chain.set_bending(0.5);
        let g = Vec3::new(0.0, 0.0, -9810.0);
        let h_s = 0.00025;
        for _ in 0..2000 {
            chain.step(h_s, &g, 2);
        }
        chain.set_held(10, true, 0.0);
        let start = chain.positions_mm[10];
        for k in 0..=16_000 {
            let t = k as f32 * h_s;
            let off = if t < 1.0 {
                Vec3::new(-6.0 * t, 0.0, 8.0 * t)
            } else {
                Vec3::new(-6.0, 0.0, 8.0 - 4.0 * (t - 1.0))
            };
            chain.positions_mm[10] = start + off;
            chain.step(h_s, &g, 2);
        }
        let between_mm = 10.0 * segment_mm;
        let apart_mm = (chain.positions_mm[10] - chain.positions_mm[0]).norm();
        let lengths: Vec<f32> = chain.positions_mm[..11]
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .collect();
        let (shortest, longest) = lengths
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &l| (a.min(l), b.max(l)));
        let strain = (apart_mm - between_mm) / between_mm;
        let straight_n = 1000.0 * strain;
        let read_n = chain.tension_n()[..10]
            .iter()
            .fold(0.0f32, |a, &b| a.max(b));
        println!(
            "apart {apart_mm:.3} mm over {between_mm:.3} mm of thread (strain {strain:.4}); segments \
             {shortest:.4}-{longest:.4} mm; tension read {read_n:.2} N, a straight stretch {straight_n:.2} N"
        );
        assert!(strain > 0.1, "strain {strain}: never drawn taut");
        assert!(
            longest <= shortest * 1.01,
            "segments {shortest}-{longest} mm: not straight and even"
        );
        assert!(
            (read_n - straight_n).abs() <= 0.05 * straight_n,
            "read {read_n} N against {straight_n} N"
        );
        for t in &chain.tension_n()[..10] {
            assert!(
                (t - read_n).abs() <= 0.05 * read_n,
                "tension {t} N along a stretch reading {read_n} N"
            );
        }
    }

    #[test]
    fn a_hole_takes_a_node_on_the_thread_hands_it_on_and_slides_through_it_keeping_the_material() {
        // Ten 2 mm segments along x.
        let nodes: Vec<Vec3> = (0..=10)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 1e-6, 1000.0, 0.0).unwrap();
        // Node 5 taken for a hole at 9.3 mm: it moves there on the thread, the segments either side follow.
        assert_eq!(chain.place_node_at(5, 9.3, 0.2), Some(9.3));
        assert!((chain.positions_mm[5].x - 9.3).abs() < 1e-5);
        assert!((chain.rest_mm()[4] - 1.3).abs() < 1e-5 && (chain.rest_mm()[5] - 2.7).abs() < 1e-5);
        // Kept 0.2 mm from its neighbours; an end node is refused.
        assert_eq!(chain.place_node_at(5, 7.0, 0.2), Some(8.2));
        assert_eq!(chain.place_node_at(0, 1.0, 0.2), None);
        assert_eq!(chain.place_node_at(10, 19.0, 0.2), None);
        assert_eq!(chain.place_node_at(5, f32::NAN, 0.2), None);
        // Handed on toward the tail: node 4 takes the hole's place and coordinate, node 5 goes halfway to node 6.
        let (at, u) = (chain.positions_mm[5], chain.node_u_mm()[5]);
        assert!(chain.hand_across(5, 4));
        assert_eq!(chain.positions_mm[4], at);
        assert_eq!(chain.node_u_mm()[4], u);
        assert!((chain.node_u_mm()[5] - 0.5 * (u + 12.0)).abs() < 1e-5);
        assert!((chain.positions_mm[5].x - 0.5 * (at.x + 12.0)).abs() < 1e-5);
        assert!((chain.rest_length_mm() - 20.0).abs() < 1e-4);
        // Not to a node that is not a neighbour, is an end, or is held.
        assert!(!chain.hand_across(4, 6));
        assert!(!chain.hand_across(1, 0));
        chain.set_held(3, true, 0.0);
        assert!(!chain.hand_across(4, 3));
        // A slide is refused at an end, at a held node, past a neighbour or when not finite.
        let slide = |lo_mm: f64, hi_mm: f64| NodeSlide {
            predicted_u_mm: 0.5 * (lo_mm + hi_mm),
            friction_n: 0.0,
            lo_mm,
            hi_mm,
            tangent: V64::x(),
        };
        let u4 = f64::from(chain.node_u_mm()[4]);
        assert!(!chain.slide_node(0, slide(0.0, 0.1)));
        assert!(!chain.slide_node(3, slide(6.0, 6.1)));
        assert!(!chain.slide_node(4, slide(u4 - 10.0, u4)));
        assert!(!chain.slide_node(4, slide(f64::NAN, u4)));
        // Pulled along +x at its far end, the thread slides through node 4 (a frictionless hole holding it in
        // place): its coordinate falls as the material runs toward the pull, and the material is kept.
        assert!(chain.hold_node(
            4,
            NodeHold {
                direction: Vec3::x(),
                place_mm: chain.positions_mm[4],
                across_n_per_mm: 10.0,
                along_n_per_mm: 10.0,
            }
        ));
        assert!(chain.slide_node(4, slide(u4 - 1.0, u4)));
        chain.forces_n[10] = Vec3::new(0.5, 0.0, 0.0);
        chain.step(0.00025, &Vec3::zeros(), 8);
        let slid = f64::from(chain.node_u_mm()[4]) - u4;
        println!("slid {slid:.5} mm in a step");
        assert!(slid < -1e-4, "it did not slide: {slid} mm");
        assert!((chain.rest_length_mm() - 20.0).abs() < 1e-4);
    }

    #[test]
    fn a_bad_chain_is_refused_and_a_bad_step_changes_nothing() {
        let p = [Vec3::zeros(), Vec3::x()];
        assert!(ThreadChain::new(&p[..1], 1e-6, 10.0, 0.0).is_none());
        assert!(ThreadChain::new(&[Vec3::zeros(), Vec3::zeros()], 1e-6, 10.0, 0.0).is_none());
        assert!(ThreadChain::new(&p, 0.0, 10.0, 0.0).is_none());
        let mut chain = ThreadChain::new(&p, 1e-6, 10.0, 0.0).unwrap();
        chain.step(f32::NAN, &Vec3::zeros(), 1);
        chain.forces_n[1] = Vec3::new(f32::NAN, 0.0, 0.0);
        chain.step(0.001, &Vec3::zeros(), 1);
        assert_eq!(chain.positions_mm, p.to_vec());
    }
}

//! A puncture hole holding the thread once the needle has passed through it, or a point of the needle's track
//! inside the tissue: a sliding node.
//!
//! Owns: [`ThreadHole`] (a material point of the surface or the volume, [`HolePoint`] in `hole_point.rs`, the thread's node it
//! holds and that node's material coordinate, its friction's state and its pull) and [`inside_by_holes`] (which
//! of the thread's points lie inside an object, from the surface holes ahead of them).
//!
//! Tracks: a thread held only at the two holes of a bite runs straight between them, and drawn tight it cuts
//! up through the tissue as a sling does (the hole on a wound's face was dragged 5 mm up toward the skin's
//! top, and closed nothing). The tissue holds a real suture all along the needle's path, so every few
//! millimetres of that path the thread passes through a ring in the volume, with the same model as a hole
//! (`thread_track.rs` lays them as the needle's tail passes). A ring inside does not change which side of the
//! surface the thread is on.
//!
//! The model, a sliding node (Sueda et al. 2011, "Eulerian-on-Lagrangian" rods; `docs/suturing.md`):
//! - **A node at the hole.** The hole owns one node of the chain, and that node's material coordinate `u_mm`
//!   (rest length from the tail) is where along the thread the hole holds it. The thread bends at the hole
//!   however it slides, and `u` is the thread's own coordinate: a hole cannot pass a neighbour, and holes keep
//!   their order along the thread by construction. (The first model held the two ends of the segment through
//!   the hole by springs and read `u` back from the geometry: drawn tight round a bend the thread ran
//!   1-4.7 mm beside its holes and their order flipped.)
//! - **Held by the tissue's give.** Inside the chain's direct solve the node is drawn by an implicit spring of
//!   the tissue's stiffness against a point ([`ThreadChain::hold_node`](super::ThreadChain::hold_node)), the
//!   same every way: the spring stands for the tissue, which is stepped apart from the thread (a stiffer one
//!   made the two swing a tick apart). It is anchored where the tissue's point would be without the pull it
//!   already carries (its place less last tick's pull over the stiffness), so once the tissue has taken the
//!   pull the node is in the hole: anchored at the place itself, the tissue's give counted twice and the node
//!   sat 2-5 mm beside its hole at 3 N. (A tissue far softer at the point than the stiffness says, by more than
//!   twice, would overshoot tick to tick: the stiffness is the squeeze over the needle's diameter.)
//! - **Sliding** is the material moving through the node, once per substep after the solve: the tensions
//!   either side, `T_prev` and `T_next`, against the capstan's drag `(e^(mu theta) - 1) T_low + mu N` (`theta`
//!   the thread's turn at the node, `N` the tissue's squeeze). Within the drag it sticks; past it `u` moves
//!   by `(|T_prev - T_next| - drag) / (k_prev + k_next)` toward the higher tension (`k` each side's `EA / l`),
//!   which leaves the two differing by the drag ([`ThreadChain::slide`](super::ThreadChain::slide)).
//! - **Passing nodes.** When a side's rest length falls under a quarter of a segment, the free node on that
//!   side takes the hole's place and material coordinate, and the old node goes halfway along the other side
//!   ([`ThreadChain::hand_across`](super::ThreadChain::hand_across)); next to a node that is not free (the
//!   tail, jaws, another hole) the hole stops a tenth of a segment short.
//! - **The tissue's side** is the spring's pull (the thread's pull on the node: across it, and the drag along
//!   it), meaned over the substeps and applied the next tick, answering as a spring
//!   ([`ThreadHole::pull_on_tissue_at_n`]), held to 20 N.
//!
//! Must not: allocate or panic; a hole whose triangle is gone, or a non-finite value, leaves the thread alone.

pub use super::hole_point::HolePoint;
use super::thread_chain::{NodeHold, ThreadChain};
use super::thread_solve::NodeSlide;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A sliding hole sticks again when the thread moves through it slower than this, mm/s.
const STOPPED_MM_S: f32 = 0.5;
/// A hole's node stops this fraction of a segment short of a neighbour that is not free.
const MIN_SEGMENT_FRACTION: f32 = 0.1;
/// A side shorter than this fraction of a segment hands its free node across.
const HAND_ACROSS_FRACTION: f32 = 0.25;
/// A hole's pull on the tissue is held to this, N (a 3-0 suture breaks at about 19 N knotted; the skin tears
/// far below).
const MAX_PULL_N: f32 = 20.0;

/// A hole holding the thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThreadHole {
    /// The punctured material point of the surface, or a point of the track inside.
    pub point: HolePoint,
    /// Where along the thread it holds it: its node's material coordinate, the rest length from the tail, mm.
    pub u_mm: f32,
    /// The tissue's squeeze on the thread, N (the friction's load with nothing pulling across).
    pub squeeze_n: f32,
    /// Thread-tissue Coulomb coefficient (the material's `needle_friction`).
    pub friction: f32,
    /// The tissue's stiffness against the point, N/mm: the spring holding the thread's node.
    pub stiffness_n_per_mm: f32,
    /// The thread slid through it at the last substep: the direction its node moved along the thread (+1:
    /// toward the free end's side, `u` falling; -1: toward the tail's), 0 while it sticks.
    pub slip: f32,
    /// The node of the chain it holds (None: none taken yet).
    node: Option<usize>,
    /// The place it holds the thread this tick, mm.
    place_mm: Vec3,
    /// How fast the thread slid through it at the last substep, mm/s (`u`'s rate).
    speed_mm_s: f32,
    /// What it held back at the last substep, N (the capstan's drag).
    drag_n: f32,
    /// The pull on the tissue summed over this tick's substeps, N (mean: over `substeps`).
    pull_sum_n: Vec3,
    substeps: u32,
    /// The mean pull of the tick before, N: the tissue carries it (`anchor_mm`).
    carried_n: Vec3,
    /// When the tissue last tore under it (`hole_tear.rs`), s of simulation time.
    torn_at_s: Option<f64>,
}

impl ThreadHole {
    /// A hole at `point` holding the thread at `u_mm`, squeezing it with `squeeze_n`, with Coulomb coefficient
    /// `friction`, in tissue of stiffness `stiffness_n_per_mm` against a point. It starts sticking, and takes
    /// its node at the first [`ThreadHole::take_node`].
    pub fn new(
        point: HolePoint,
        u_mm: f32,
        squeeze_n: f32,
        friction: f32,
        stiffness_n_per_mm: f32,
    ) -> Self {
        let clean = |v: f32| if v.is_finite() { v.max(0.0) } else { 0.0 };
        Self {
            point,
            stiffness_n_per_mm: clean(stiffness_n_per_mm),
            friction: clean(friction),
            u_mm: clean(u_mm),
            squeeze_n: clean(squeeze_n),
            slip: 0.0,
            node: None,
            place_mm: Vec3::zeros(),
            speed_mm_s: 0.0,
            drag_n: clean(friction) * clean(squeeze_n),
            pull_sum_n: Vec3::zeros(),
            substeps: 0,
            carried_n: Vec3::zeros(),
            torn_at_s: None,
        }
    }

    /// The tissue tore under it at `now_s` (`hole_tear.rs`): it holds the thread at `point` now, where the slit
    /// reached, and that point carries no pull yet; it sticks until the thread slides again.
    pub fn tear_to(&mut self, point: HolePoint, now_s: f64) {
        self.point = point;
        self.pull_sum_n = Vec3::zeros();
        self.substeps = 0;
        self.carried_n = Vec3::zeros();
        self.slip = 0.0;
        self.speed_mm_s = 0.0;
        self.torn_at_s = Some(now_s);
    }

    /// When the tissue last tore under it, s of simulation time (None: never).
    pub fn torn_at_s(&self) -> Option<f64> {
        self.torn_at_s
    }

    /// Before the thread's substeps: read where the tissue holds the hole now. False when it cannot (its
    /// triangle is gone): the hole is to be let go.
    pub fn place(&mut self, model: &MassSpringModel, state: &TissueState) -> bool {
        self.carried_n = self.pull_on_tissue_n();
        self.pull_sum_n = Vec3::zeros();
        self.substeps = 0;
        match self.point.position_mm(model, state) {
            Some(p) if p.iter().all(|c| c.is_finite()) => {
                self.place_mm = p;
                true
            }
            _ => false,
        }
    }

    /// Where it holds the thread this tick, mm.
    pub fn place_mm(&self) -> Vec3 {
        self.place_mm
    }

    /// The node of the chain it holds (None: none taken yet).
    pub fn node(&self) -> Option<usize> {
        self.node
    }

    /// Whether it holds node `i`.
    pub fn holds_node(&self, i: usize) -> bool {
        self.node == Some(i)
    }

    /// How fast the thread slid through it at the last substep, mm/s (`u`'s rate).
    pub fn speed_mm_s(&self) -> f32 {
        self.speed_mm_s
    }

    /// What it held back at the last substep, N (the capstan's drag).
    pub fn drag_n(&self) -> f32 {
        self.drag_n
    }

    /// The mean pull of the thread on the tissue through it over the last tick, world, N.
    pub fn pull_on_tissue_n(&self) -> Vec3 {
        if self.substeps == 0 {
            return Vec3::zeros();
        }
        self.pull_sum_n / self.substeps as f32
    }

    /// The pull on the tissue with its point at `now_mm` (a tissue substep's place, not the tick's): the
    /// tick's mean pull, less the spring's stiffness times how far the point has moved since, held to 20 N.
    /// The tissue then answers a spring, not a force fixed for the tick: a fixed force a tick late set a
    /// hole on a wound's edge swinging 1.7 mm each way every tick.
    pub fn pull_on_tissue_at_n(&self, now_mm: &Vec3) -> Vec3 {
        let pull = self.pull_on_tissue_n();
        let moved = now_mm - self.place_mm;
        if self.substeps == 0 || !moved.iter().all(|c| c.is_finite()) {
            return pull;
        }
        let pull = pull - moved * self.stiffness_n_per_mm;
        pull * (MAX_PULL_N / pull.norm().max(MAX_PULL_N))
    }

    /// Take a node of `chain` for the hole at its `u_mm` (once; true when it has one): of the two nodes either
    /// side of that coordinate, the nearer one that is interior, not held and not `claimed` (by other holes),
    /// moved there on the thread as it lies ([`ThreadChain::place_node_at`]); `claimed` is marked. A hole with
    /// no free node near holds nothing until one is.
    pub fn take_node(&mut self, chain: &mut ThreadChain, claimed: &mut [bool]) -> bool {
        if self.node.is_some() {
            return true;
        }
        let n = chain.positions_mm.len();
        if n < 3 || claimed.len() < n {
            return false;
        }
        let nominal = chain.rest_length_mm() / (n - 1) as f32;
        let u = self.u_mm;
        let node_u = chain.node_u_mm();
        let after = node_u.partition_point(|&c| c <= u).clamp(1, n - 1);
        let mut candidates = [after - 1, after];
        if (node_u[after - 1] - u).abs() > (node_u[after] - u).abs() {
            candidates.swap(0, 1);
        }
        for i in candidates {
            let free = i > 0 && i + 1 < n && chain.inverse_mass_per_kg()[i] != 0.0 && !claimed[i];
            if !free {
                continue;
            }
            if let Some(u) = chain.place_node_at(i, u, MIN_SEGMENT_FRACTION * nominal) {
                self.u_mm = u;
                self.node = Some(i);
                claimed[i] = true;
                return true;
            }
        }
        false
    }

    /// Where the tissue's point would be without the pull it carries (the last tick's): its place, less that
    /// pull over its stiffness, mm. The spring standing for the tissue's give is anchored there, so the thread
    /// feels the tissue's compliance and still runs through the hole itself once the tissue has taken the pull
    /// (anchored at the place, the node sat the pull over the stiffness beside it: 2-5 mm at 3 N on skin).
    fn anchor_mm(&self) -> Vec3 {
        let k = self.stiffness_n_per_mm;
        if k > 0.0 {
            self.place_mm - self.carried_n / k
        } else {
            self.place_mm
        }
    }

    /// How it holds its node in the next substep: a spring of the tissue's stiffness toward its anchor (the
    /// tissue's point unloaded), the same every way (None: no node, or no stiffness).
    pub fn node_hold(&self) -> Option<(usize, NodeHold)> {
        let k = self.stiffness_n_per_mm;
        let node = self.node?;
        (k > 0.0).then_some((
            node,
            NodeHold {
                direction: Vec3::x(),
                place_mm: self.anchor_mm(),
                across_n_per_mm: k,
                along_n_per_mm: k,
            },
        ))
    }

    /// How the thread slides through its node in the next substep of `h_s`, while it slides (None: it sticks,
    /// or has no node): its material coordinate a variable of the chain's solve, with the drag against the way
    /// it slides, and the node's neighbours no nearer than a tenth of a segment ([`NodeSlide`]).
    pub fn node_slide(&self, chain: &ThreadChain, h_s: f32) -> Option<(usize, NodeSlide)> {
        let i = self.node?;
        let node_u = chain.node_u_mm();
        let n = node_u.len();
        if self.slip == 0.0 || i == 0 || i + 1 >= n || h_s.is_nan() || h_s <= 0.0 {
            return None;
        }
        let min = MIN_SEGMENT_FRACTION * chain.rest_length_mm() / (n - 1) as f32;
        let u = f64::from(node_u[i]);
        // `slip` +1: `u` falling.
        let (lo, hi) = if self.slip > 0.0 {
            (f64::from(node_u[i - 1] + min), u)
        } else {
            (u, f64::from(node_u[i + 1] - min))
        };
        let x = &chain.positions_mm;
        let tangent = (x[i + 1] - x[i - 1]).try_normalize(1e-9)?.cast::<f64>();
        (lo <= hi).then_some((
            i,
            NodeSlide {
                predicted_u_mm: u + f64::from(self.speed_mm_s * h_s),
                friction_n: f64::from(-self.slip * self.drag_n),
                lo_mm: lo,
                hi_mm: hi,
                tangent,
            },
        ))
    }

    /// After a substep of `h_s` (its node held, and slid if it slides): how far the thread slid; the stick or
    /// slide test for the next substep (it slides when the tensions either side differ by more than the
    /// capstan's drag, and sticks again when it stops); a free node handed across when a side has grown short
    /// (`claimed`, per node, kept up); and the pull on the tissue, its spring's, summed.
    pub fn after_substep(&mut self, chain: &mut ThreadChain, claimed: &mut [bool], h_s: f32) {
        let Some(i) = self.node else {
            return;
        };
        let n = chain.positions_mm.len();
        if i == 0 || i + 1 >= n || claimed.len() < n || h_s.is_nan() || h_s <= 0.0 {
            return;
        }
        let nominal = chain.rest_length_mm() / (n - 1) as f32;
        let x = &chain.positions_mm;
        let tension = |s: usize| {
            let t = chain.tension_n()[s];
            if t.is_finite() { t.max(0.0) } else { 0.0 }
        };
        let (behind_n, ahead_n) = (tension(i - 1), tension(i));
        let turn_rad = (x[i] - x[i - 1])
            .try_normalize(1e-9)
            .zip((x[i + 1] - x[i]).try_normalize(1e-9))
            .map_or(0.0, |(a, b)| a.dot(&b).clamp(-1.0, 1.0).acos());
        let drag_n = ((self.friction * turn_rad).exp() - 1.0) * behind_n.min(ahead_n)
            + self.friction * self.squeeze_n;
        let u = chain.node_u_mm()[i];
        let spring_n = (x[i] - self.anchor_mm()) * self.stiffness_n_per_mm;
        if !(drag_n.is_finite() && u.is_finite() && spring_n.iter().all(|c| c.is_finite())) {
            return;
        }
        if self.slip == 0.0 {
            // It slides toward the higher tension (+1: `u` falling, toward the free end's side).
            if (behind_n - ahead_n).abs() > drag_n {
                self.slip = if behind_n > ahead_n { -1.0 } else { 1.0 };
            }
            self.speed_mm_s = 0.0;
        } else {
            self.speed_mm_s = (u - self.u_mm) / h_s;
            if -self.speed_mm_s * self.slip < STOPPED_MM_S {
                self.slip = 0.0;
                self.speed_mm_s = 0.0;
            }
        }
        self.drag_n = drag_n;
        // A side grown short: its free node takes the hole's place.
        let free =
            |j: usize| j > 0 && j + 1 < n && chain.inverse_mass_per_kg()[j] != 0.0 && !claimed[j];
        let short = HAND_ACROSS_FRACTION * nominal;
        let to = if chain.rest_mm()[i - 1] < short && free(i - 1) {
            Some(i - 1)
        } else if chain.rest_mm()[i] < short && free(i + 1) {
            Some(i + 1)
        } else {
            None
        };
        if let Some(to) = to
            && chain.hand_across(i, to)
        {
            claimed[i] = false;
            claimed[to] = true;
            self.node = Some(to);
        }
        self.u_mm = u;
        // The tissue feels its spring's pull toward the node (the thread's pull on the node).
        self.pull_sum_n += spring_n * (MAX_PULL_N / spring_n.norm().max(MAX_PULL_N));
        self.substeps += 1;
    }
}

/// Before a tick's substeps: mark in `claimed` (per node) the nodes the `holes` and `rings` hold, then give
/// each without one a node of `chain` ([`ThreadHole::take_node`]), the holes first.
pub fn take_nodes(
    holes: &mut [ThreadHole],
    rings: &mut [ThreadHole],
    chain: &mut ThreadChain,
    claimed: &mut [bool],
) {
    claimed.fill(false);
    for i in holes.iter().chain(rings.iter()).filter_map(|h| h.node()) {
        if let Some(c) = claimed.get_mut(i) {
            *c = true;
        }
    }
    for hole in holes.iter_mut().chain(rings.iter_mut()) {
        hole.take_node(chain, claimed);
    }
}

/// Whether the thread's point at arc length `u_mm` lies inside object `object`, from the holes: the thread starts
/// (at its tail) inside an object when an odd number of its holes in that object lie ahead along it, and each
/// hole it passes takes it through the surface. Holes are in any order.
pub fn inside_by_holes(holes: &[ThreadHole], object: u16, u_mm: f32) -> bool {
    holes
        .iter()
        .filter(|h| h.point.is_surface() && h.point.object() == object && h.u_mm > u_mm)
        .count()
        % 2
        == 1
}

#[cfg(test)]
mod tests {
    use super::super::SurfacePoint;
    use super::super::ThreadChain;
    use super::*;

    fn hole_at(place: Vec3, u_mm: f32, squeeze_n: f32, friction: f32) -> ThreadHole {
        let mut h = ThreadHole::new(
            HolePoint::Surface(SurfacePoint {
                object: 0,
                triangle: 0,
                barycentric: [1.0, 0.0, 0.0],
            }),
            u_mm,
            squeeze_n,
            friction,
            1.0,
        );
        h.place_mm = place;
        h
    }

    /// One substep of 0.25 ms of a chain of 2 mm segments through `holes`, as `SutureThread::step` takes it
    /// (without gravity or contacts).
    fn substep(chain: &mut ThreadChain, holes: &mut [ThreadHole]) {
        let mut claimed = vec![false; chain.positions_mm.len()];
        for i in holes.iter().filter_map(|h| h.node()) {
            claimed[i] = true;
        }
        for hole in holes.iter_mut() {
            assert!(hole.take_node(chain, &mut claimed), "no node for {hole:?}");
            let (i, hold) = hole.node_hold().unwrap();
            assert!(chain.hold_node(i, hold));
            if let Some((i, slide)) = hole.node_slide(chain, 0.00025) {
                assert!(chain.slide_node(i, slide), "{slide:?} refused");
            }
        }
        chain.step(0.00025, &Vec3::zeros(), 2);
        for hole in holes.iter_mut() {
            hole.after_substep(chain, &mut claimed, 0.00025);
        }
    }

    /// A free 80 mm thread (0.2 g a node: the drag is read before it has run through) along x through holes at
    /// `at_mm` from its middle (squeeze 1 N, `mu`), its far end pulled along +x with `pull_n` (ramped up over the
    /// first half) for `ticks` ms (no gravity): the first hole's arc length at the end, from the middle, and the
    /// holes' summed mean pull on the tissue over the second half. (A thread sliding freely at 0.2 N runs 13 mm
    /// through in 40 ms: it has 40 mm to run before its end reaches a hole.)
    fn pull_through(pull_n: f32, mu: f32, ticks: usize, at_mm: &[f32]) -> (f32, Vec3) {
        let nodes: Vec<Vec3> = (0..=40)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-4, 1000.0, 5.0).unwrap();
        let mut holes: Vec<ThreadHole> = at_mm
            .iter()
            .map(|&u| hole_at(Vec3::new(40.0 + u, 0.0, 0.0), 40.0 + u, 1.0, mu))
            .collect();
        let mut pull_sum = Vec3::zeros();
        for tick in 0..ticks {
            for hole in &mut holes {
                hole.pull_sum_n = Vec3::zeros();
                hole.substeps = 0;
            }
            for _ in 0..4 {
                // Ramped over the first half (a step would overshoot the spring twice over).
                let ramp = (tick as f32 / (ticks / 2) as f32).min(1.0);
                chain.forces_n[40] = Vec3::new(pull_n * ramp, 0.0, 0.0);
                substep(&mut chain, &mut holes);
            }
            if tick >= ticks / 2 {
                pull_sum += holes.iter().map(|h| h.pull_on_tissue_n()).sum::<Vec3>();
            }
        }
        (holes[0].u_mm - 40.0, pull_sum / (ticks - ticks / 2) as f32)
    }

    #[test]
    fn a_thread_pulled_within_the_friction_sticks_and_past_it_slides_with_the_friction_as_its_drag()
    {
        // mu 0.3 on a 1 N squeeze: 0.3 N holds it.
        let (u, pull) = pull_through(0.2, 0.3, 200, &[20.0]);
        println!("0.2 N: u {u:.3} mm, pull on the tissue {pull:?} N");
        assert!((u - 20.0).abs() < 0.5, "it slid at 0.2 N: u {u} mm");
        assert!((pull.x - 0.2).abs() < 0.02, "{pull:?}: not the 0.2 N pull");
        let (u, pull) = pull_through(0.5, 0.3, 40, &[20.0]);
        println!("0.5 N: u {u:.3} mm, pull on the tissue {pull:?} N");
        assert!(u < 19.0, "it held at 0.5 N: u {u} mm");
        assert!(
            (pull.x - 0.3).abs() < 0.03,
            "{pull:?}: sliding, the tissue should feel the 0.3 N drag"
        );
        let (u_free, pull) = pull_through(0.5, 0.0, 40, &[20.0]);
        println!("0.5 N, no friction: u {u_free:.3} mm, pull {pull:?} N");
        assert!(u_free < u, "friction did not slow it: {u_free} vs {u} mm");
        assert!(pull.norm() < 0.01, "{pull:?}");
    }

    #[test]
    fn through_two_holes_the_thread_holds_twice_the_pull_and_drags_twice_as_hard() {
        // 0.5 N slides it through one hole (above); two hold it.
        let (u, pull) = pull_through(0.5, 0.3, 200, &[14.0, 26.0]);
        println!("two holes, 0.5 N: u {u:.3} mm, pull on the tissue {pull:?} N");
        assert!(
            (u - 14.0).abs() < 0.5,
            "it slid through two holes at 0.5 N: u {u} mm"
        );
        assert!((pull.x - 0.5).abs() < 0.03, "{pull:?}");
        // 0.9 N slides it, against 0.6 N of drag.
        let (u, pull) = pull_through(0.9, 0.3, 40, &[14.0, 26.0]);
        println!("two holes, 0.9 N: u {u:.3} mm, pull on the tissue {pull:?} N");
        assert!(u < 13.0, "it held at 0.9 N: u {u} mm");
        assert!(
            (pull.x - 0.6).abs() < 0.06,
            "{pull:?}: sliding through two holes, the tissue should feel 0.6 N of drag"
        );
    }

    /// A thread turning 90 degrees at a hole (squeeze 0.1 N, `mu` 0.3): 20 mm along x to the hole, 20 mm along y
    /// after it, 0.2 N pulling its tail end back along -x and `pull_n` its far end along +y (ramped up over the
    /// first half of 0.2 s). The hole's arc length at the end.
    fn pull_round_a_corner(pull_n: f32) -> f32 {
        let nodes: Vec<Vec3> = (0..=20)
            .map(|i| {
                if i <= 10 {
                    Vec3::new(2.0 * i as f32, 0.0, 0.0)
                } else {
                    Vec3::new(20.0, 2.0 * (i - 10) as f32, 0.0)
                }
            })
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-4, 1000.0, 5.0).unwrap();
        let mut hole = hole_at(Vec3::new(20.0, 0.0, 0.0), 20.0, 0.1, 0.3);
        for tick in 0..200 {
            for _ in 0..4 {
                let ramp = (tick as f32 / 100.0).min(1.0);
                chain.forces_n[0] = Vec3::new(-0.2 * ramp, 0.0, 0.0);
                chain.forces_n[20] = Vec3::new(0.0, pull_n * ramp, 0.0);
                substep(&mut chain, std::slice::from_mut(&mut hole));
            }
        }
        hole.u_mm
    }

    #[test]
    fn a_thread_turning_through_a_hole_holds_by_the_capstan() {
        // e^(0.3 pi / 2) = 1.60: 0.2 N holds 0.32 N round the corner, and the squeeze 0.03 N more. A straight
        // thread would slide at 0.23 N.
        let held = pull_round_a_corner(0.3);
        let slid = pull_round_a_corner(0.45);
        println!(
            "round a 90 degree turn: pulled with 0.3 N the hole is at {held:.3} mm, with 0.45 N at {slid:.3} mm"
        );
        assert!(
            (held - 20.0).abs() < 0.5,
            "0.3 N pulled it round: u {held} mm"
        );
        assert!(slid < 18.0, "0.45 N did not pull it round: u {slid} mm");
    }

    #[test]
    fn a_hole_far_off_or_a_broken_thread_never_pulls_the_tissue_past_its_limit_or_with_nan() {
        // The thread 100 mm from its hole (a tissue that jumped, say): the pull is held to the limit.
        let nodes: Vec<Vec3> = (0..=20)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-7, 1000.0, 5.0).unwrap();
        let mut far = hole_at(Vec3::new(20.0, 100.0, 0.0), 20.0, 1.0, 0.3);
        far.stiffness_n_per_mm = 50.0;
        substep(&mut chain, std::slice::from_mut(&mut far));
        let pull = far.pull_on_tissue_n();
        println!("a hole 100 mm off: pull {pull:?} N");
        assert!(pull.iter().all(|c| c.is_finite()));
        assert!(pull.norm() <= MAX_PULL_N * 1.0001, "{pull:?}");
        assert!(pull.norm() > 1.0, "the far hole did not pull: {pull:?}");
        // A non-finite thread: the hole slides nothing and pulls nothing.
        let mut chain = ThreadChain::new(&nodes, 2e-7, 1000.0, 5.0).unwrap();
        let mut hole = hole_at(Vec3::new(20.0, 0.0, 0.0), 20.0, 1.0, 0.3);
        let mut claimed = vec![false; nodes.len()];
        assert!(hole.take_node(&mut chain, &mut claimed));
        assert_eq!(hole.node(), Some(10));
        chain.positions_mm[10] = Vec3::new(f32::NAN, 0.0, 0.0);
        hole.after_substep(&mut chain, &mut claimed, 0.00025);
        assert_eq!(hole.pull_on_tissue_n(), Vec3::zeros());
        assert!(hole.u_mm.is_finite());
        assert_eq!(chain.rest_mm(), &[2.0; 20][..]);
    }

    #[test]
    fn the_tissue_answers_a_hole_as_a_spring_and_a_sliding_hole_passes_it_the_drag_only() {
        // A thread held still along x through a sticking hole at 20 mm, pulled 0.2 N (within the 0.3 N
        // friction): the tissue's point where the hole is feels the tick's pull; moved 0.1 mm across the thread
        // and 0.1 mm along it, it feels the springs' pull less their stiffness times that.
        let nodes: Vec<Vec3> = (0..=20)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-4, 1000.0, 5.0).unwrap();
        let place = Vec3::new(20.0, 0.0, 0.0);
        let mut hole = hole_at(place, 20.0, 1.0, 0.3);
        hole.stiffness_n_per_mm = 2.0;
        chain.forces_n[20] = Vec3::new(0.2, 0.0, 0.0);
        for _ in 0..400 {
            hole.pull_sum_n = Vec3::zeros();
            hole.substeps = 0;
            substep(&mut chain, std::slice::from_mut(&mut hole));
        }
        assert_eq!(hole.slip, 0.0, "it slid within the friction");
        let pull = hole.pull_on_tissue_n();
        assert_eq!(hole.pull_on_tissue_at_n(&place), pull);
        let moved = Vec3::new(0.1, 0.1, 0.0);
        let at = hole.pull_on_tissue_at_n(&(place + moved));
        // Its node, held by the tissue's stiffness every way.
        let expected = pull - moved * 2.0;
        println!("pull {pull:?} N; moved {moved:?} mm: {at:?} N (expected {expected:?})");
        assert!((at - expected).norm() < 1e-4, "{at:?} vs {expected:?}");
        // Sliding, the tissue feels the drag (0.3 N here) along the thread however fast the thread is flicked
        // through: a pull of 5 N drawn through in one go.
        let (_, pull) = pull_through(5.0, 0.3, 6, &[20.0]);
        println!("flicked through at 5 N: the tissue feels {pull:?} N");
        assert!(pull.x.abs() <= 0.3 * 1.001, "{pull:?}");
    }

    #[test]
    fn once_the_tissue_has_taken_the_pull_the_thread_runs_through_the_hole_itself() {
        // A thread along x held by a sticking hole at 20 mm (2 N/mm), drawn 0.2 N along x at its far end (within
        // the 0.3 N friction), in a tissue as stiff at the point as the hole says: each tick the hole's place
        // is where the last tick's pull took the tissue's point. The spring anchored at the place itself would
        // leave the node 0.1 mm (the pull over the stiffness) beyond it.
        let nodes: Vec<Vec3> = (0..=20)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-4, 1000.0, 5.0).unwrap();
        let rest = Vec3::new(20.0, 0.0, 0.0);
        let mut hole = hole_at(rest, 20.0, 1.0, 0.3);
        hole.stiffness_n_per_mm = 2.0;
        for _ in 0..400 {
            hole.carried_n = hole.pull_on_tissue_n();
            hole.place_mm = rest + hole.carried_n / 2.0;
            hole.pull_sum_n = Vec3::zeros();
            hole.substeps = 0;
            for _ in 0..4 {
                chain.forces_n[20] = Vec3::new(0.2, 0.0, 0.0);
                substep(&mut chain, std::slice::from_mut(&mut hole));
            }
        }
        let node = chain.positions_mm[hole.node().unwrap()];
        let pull = hole.pull_on_tissue_n();
        println!(
            "pull {pull:?} N; the tissue's point at {:?}, the thread's node at {node:?}",
            hole.place_mm
        );
        assert_eq!(hole.slip, 0.0);
        assert!((pull.x - 0.2).abs() < 0.01, "{pull:?}");
        assert!(
            (hole.place_mm.x - 20.1).abs() < 0.005,
            "{:?}",
            hole.place_mm
        );
        assert!((node - hole.place_mm).norm() < 0.005, "{node:?}");
    }

    #[test]
    fn the_thread_is_inside_between_holes_of_one_object() {
        let holes = [
            hole_at(Vec3::zeros(), 10.0, 0.0, 0.0),
            hole_at(Vec3::zeros(), 30.0, 0.0, 0.0),
        ];
        assert!(!inside_by_holes(&holes, 0, 5.0));
        assert!(inside_by_holes(&holes, 0, 20.0));
        assert!(!inside_by_holes(&holes, 0, 40.0));
        assert!(!inside_by_holes(&holes, 1, 20.0));
        // One hole ahead: the tail end is inside (the needle's tail has passed the entry, not the exit).
        assert!(inside_by_holes(&holes[1..], 0, 20.0));
    }
}

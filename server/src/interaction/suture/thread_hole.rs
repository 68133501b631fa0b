//! A puncture hole holding the thread once the needle has passed through it, or a point of the needle's track
//! inside the tissue: a sliding ring.
//!
//! Owns: [`ThreadHole`] (a material point of the surface or the volume, [`HolePoint`], where along the thread it
//! holds it, its friction's state and its pull) and [`inside_by_holes`] (which of the thread's points lie inside
//! an object, from the surface holes ahead of them).
//!
//! Tracks: a thread held only at the two holes of a bite runs straight between them, and drawn tight it cuts
//! up through the tissue as a sling does (the hole on a wound's face was dragged 5 mm up toward the skin's
//! top, and closed nothing). The tissue holds a real suture all along the needle's path, so every few
//! millimetres of that path the thread passes through a ring in the volume, with the same model as a hole
//! (`thread.rs` lays them as the needle's tail passes). A ring inside does not change which side of the surface
//! the thread is on.
//!
//! The model (`docs/suturing.md`, "Holes take the thread"):
//! - **Where.** The hole holds the thread at an arc length `u_mm` from its tail node (a material point of the
//!   thread). It starts at 0 when the needle's tail leaves it. Each substep it holds the two end nodes of the
//!   segment through it, each by half the tissue's stiffness, so the segment passes through the hole however
//!   the thread bends there.
//! - **In the solve, not after it.** The nodes are held by implicit springs inside the chain's direct length
//!   solve ([`ThreadChain::hold_node`](super::ThreadChain::hold_node)): light nodes put back after the solve
//!   would show only their own inertia, and a thread drawn through would never read more than a micronewton
//!   against the friction.
//! - **Sticking** the ends are pinned at the places of their material points. It slides when the tensions the
//!   solve found beyond them differ by more than the capstan holds: `(e^(mu theta) - 1)` times the lower plus
//!   `mu` times the tissue's squeeze on the thread, `theta` the angle the thread turns through at the ends.
//! - **Sliding** the ends run on the segment's line through the hole (the springs across only), the friction a
//!   damper along it, implicit and as stiff as gives that drag at the speed it slid at: the tensions either
//!   side then differ by the drag, and a thread drawn through several holes drags by the sum. `u` is read
//!   again from where the ends lie on the line; it sticks again when the thread stops or turns back.
//! - **The tissue's side** is the mean over the substeps of the springs' pull (across, and the drag along while
//!   sliding; [`ThreadHole::pull_on_tissue_n`]), applied the next tick, held to 20 N.
//!
//! Must not: allocate or panic; a hole whose triangle is gone, or a non-finite value, leaves the thread alone.

use super::SurfacePoint;
use super::thread_chain::NodeHold;
use super::volume_point::VolumePoint;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A sliding hole sticks again when the thread moves through it slower than this, mm/s.
const STOPPED_MM_S: f32 = 0.5;
/// The friction of a sliding hole is a damper giving `mu N` at the speed it slides, taken as at least this,
/// mm/s (slower, less: it cannot push the thread back).
const REGULARISED_MM_S: f32 = 1.0;
/// A hole's pull on the tissue is held to this, N (a 3-0 suture breaks at about 19 N knotted; the skin tears
/// far below).
const MAX_PULL_N: f32 = 20.0;

/// Where a ring holds the thread: a hole in the surface, or a point of the needle's track inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HolePoint {
    /// A puncture hole: the thread crosses the surface there.
    Surface(SurfacePoint),
    /// A point of the needle's track inside the volume.
    Volume(VolumePoint),
}

impl HolePoint {
    /// The object it is in.
    pub fn object(&self) -> u16 {
        match self {
            HolePoint::Surface(p) => p.object,
            HolePoint::Volume(p) => p.object,
        }
    }

    /// A hole in the surface (not a point of a track inside).
    pub fn is_surface(&self) -> bool {
        matches!(self, HolePoint::Surface(_))
    }

    /// Where it is now, mm (None: its triangle or tetrahedron is gone).
    pub fn position_mm(&self, model: &MassSpringModel, state: &TissueState) -> Option<Vec3> {
        match self {
            HolePoint::Surface(p) => p.position_mm(model, state),
            HolePoint::Volume(p) => p.position_mm(model, state),
        }
    }

    /// Spread `force_n` on the nodes carrying it, by their weights, into `forces_n` (a corner out of range is
    /// skipped; a point whose element is gone spreads nothing).
    pub fn spread(&self, model: &MassSpringModel, force_n: &Vec3, forces_n: &mut [Vec3]) {
        // The corners and their weights: a triangle's three, or a tetrahedron's four.
        let (corners, weights): ([u32; 4], [f32; 4]) = match self {
            HolePoint::Surface(p) => match p.corners(model) {
                Some([a, b, c]) => (
                    [a, b, c, 0],
                    [p.barycentric[0], p.barycentric[1], p.barycentric[2], 0.0],
                ),
                None => return,
            },
            HolePoint::Volume(p) => match p.corners(model) {
                Some(corners) => (corners, p.barycentric),
                None => return,
            },
        };
        for (&c, &b) in corners.iter().zip(&weights).filter(|(_, b)| **b != 0.0) {
            if let Some(f) = forces_n.get_mut(c as usize) {
                *f += force_n * b;
            }
        }
    }
}

/// A hole holding the thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThreadHole {
    /// The punctured material point of the surface, or a point of the track inside.
    pub point: HolePoint,
    /// Where along the thread it holds it: the arc length from the tail node, mm (rest lengths).
    pub u_mm: f32,
    /// The tissue's squeeze on the thread, N (the friction's load with nothing pulling across).
    pub squeeze_n: f32,
    /// Thread-tissue Coulomb coefficient (the material's `needle_friction`).
    pub friction: f32,
    /// The tissue's stiffness against the point, N/mm: the spring holding the thread's node.
    pub stiffness_n_per_mm: f32,
    /// The thread slides through it: the direction its node moves along the thread (+1: toward the free end's
    /// side, `u` falling; -1: toward the tail's), 0 while it sticks.
    pub slip: f32,
    /// The place it holds the thread this tick, mm.
    place_mm: Vec3,
    /// This substep's holds: the segment's end nodes and how.
    holds: [Option<(usize, NodeHold)>; 2],
    /// How fast the thread slid through it at the last substep, mm/s (`u`'s rate).
    speed_mm_s: f32,
    /// What it held back at the last substep, N (its drag while sliding).
    drag_n: f32,
    /// The pull on the tissue summed over this tick's substeps, N (mean: over `substeps`).
    pull_sum_n: Vec3,
    substeps: u32,
    /// The springs' stiffness on the tissue's point at the last substep, N/mm: across the thread, and along it
    /// (while it sticks), with the thread's direction there.
    across_n_per_mm: f32,
    along_n_per_mm: f32,
    direction: Vec3,
    /// It holds nothing (another ring holds its segment).
    resting: bool,
}

impl ThreadHole {
    /// A hole at `point` holding the thread at `u_mm`, squeezing it with `squeeze_n`, with Coulomb coefficient
    /// `friction`, in tissue of stiffness `stiffness_n_per_mm` against a point. It starts sticking.
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
            place_mm: Vec3::zeros(),
            holds: [None, None],
            speed_mm_s: 0.0,
            drag_n: clean(friction) * clean(squeeze_n),
            pull_sum_n: Vec3::zeros(),
            substeps: 0,
            across_n_per_mm: 0.0,
            along_n_per_mm: 0.0,
            direction: Vec3::zeros(),
            resting: false,
        }
    }

    /// Before the thread's substeps: read where the tissue holds the hole now. False when it cannot (its
    /// triangle is gone): the hole is to be let go.
    pub fn place(&mut self, model: &MassSpringModel, state: &TissueState) -> bool {
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

    /// Whether it holds nothing this substep (another ring holds its segment): [`ThreadHole::node_holds`] then
    /// returns none.
    pub fn set_resting(&mut self, resting: bool) {
        self.resting = resting;
    }

    /// Whether it holds nothing this substep ([`ThreadHole::set_resting`]).
    pub fn is_resting(&self) -> bool {
        self.resting
    }

    /// Where it holds the thread this tick, mm.
    pub fn place_mm(&self) -> Vec3 {
        self.place_mm
    }

    /// Whether it holds node `i` this substep (between [`ThreadHole::node_holds`] and
    /// [`ThreadHole::after_substep`]).
    pub fn holds_node(&self, i: usize) -> bool {
        self.holds.iter().flatten().any(|(k, _)| *k == i)
    }

    /// The mean pull of the thread on the tissue through it over the last tick, world, N.
    pub fn pull_on_tissue_n(&self) -> Vec3 {
        if self.substeps == 0 {
            return Vec3::zeros();
        }
        self.pull_sum_n / self.substeps as f32
    }

    /// The pull on the tissue with its point at `now_mm` (a tissue substep's place, not the tick's): the
    /// tick's mean pull, less the springs' stiffness times how far the point has moved since, held to 20 N.
    /// The tissue then answers a spring, not a force fixed for the tick: a fixed force a tick late set a
    /// hole on a wound's edge swinging 1.7 mm each way every tick.
    pub fn pull_on_tissue_at_n(&self, now_mm: &Vec3) -> Vec3 {
        let pull = self.pull_on_tissue_n();
        let moved = now_mm - self.place_mm;
        if self.substeps == 0 || !moved.iter().all(|c| c.is_finite()) {
            return pull;
        }
        let t = self.direction;
        let along = t.dot(&moved);
        let back = (moved - t * along) * self.across_n_per_mm + t * (along * self.along_n_per_mm);
        let pull = pull - back;
        pull * (MAX_PULL_N / pull.norm().max(MAX_PULL_N))
    }

    /// The nodes it holds this substep of `h_s` (the two ends of the segment through it) of a thread at `now`
    /// with inverse masses `w` and rest segment `segment_mm`, and how ([`NodeHold`]). A node held already (the
    /// tail on the needle) is left to its holder; with neither end free `u` is read again from the thread.
    pub fn node_holds(
        &mut self,
        now: &[Vec3],
        w: &[f32],
        segment_mm: f32,
        h_s: f32,
    ) -> [Option<(usize, NodeHold)>; 2] {
        self.holds = [None, None];
        if self.resting {
            return self.holds;
        }
        let segments = now.len().min(w.len()).saturating_sub(1);
        let k = self.stiffness_n_per_mm;
        if segments == 0 || !(segment_mm > 0.0 && h_s > 0.0) || k <= 0.0 {
            return self.holds;
        }
        let s = ((self.u_mm / segment_mm) as usize).min(segments - 1);
        let Some(direction) = (now[s + 1] - now[s]).try_normalize(1e-6) else {
            return self.holds;
        };
        if w[s] == 0.0 && w[s + 1] == 0.0 {
            self.u_mm = nearest_arc_length(now, s, segment_mm, &self.place_mm).unwrap_or(self.u_mm);
            return self.holds;
        }
        // Each end by a spring of half the tissue's stiffness: the two hold the segment through the place.
        for (slot, i) in [s, s + 1].into_iter().enumerate() {
            if w[i] == 0.0 {
                continue;
            }
            let (place_mm, along_n_per_mm) = if self.slip == 0.0 {
                // Sticking: its material point on the place, the node that far along from it.
                (
                    self.place_mm + direction * (i as f32 * segment_mm - self.u_mm),
                    0.5 * k,
                )
            } else {
                // Sliding: on the rail, the friction a damper from where the node is now along it, as stiff
                // as gives the drag at the speed it slid at.
                let on_rail = self.place_mm + direction * direction.dot(&(now[i] - self.place_mm));
                let speed = self.speed_mm_s.abs().max(REGULARISED_MM_S);
                (on_rail, 0.5 * self.drag_n / speed / h_s)
            };
            self.holds[slot] = Some((
                i,
                NodeHold {
                    direction,
                    place_mm,
                    across_n_per_mm: 0.5 * k,
                    along_n_per_mm,
                },
            ));
        }
        self.holds
    }

    /// After the substep of `h_s`: the springs' pull, the stick or slide test and `u` read again, from where the
    /// held nodes ended (`now`, rest segment `segment_mm`) and the segments' tensions `tension_n` (the solve's,
    /// with the nodes held).
    pub fn after_substep(&mut self, now: &[Vec3], tension_n: &[f32], segment_mm: f32, h_s: f32) {
        let holds = std::mem::take(&mut self.holds);
        let Some(&(first, hold)) = holds.iter().flatten().next() else {
            return;
        };
        // The segment through the hole runs from node s to s + 1.
        let s = if holds[0].is_some() { first } else { first - 1 };
        let t = hold.direction;
        let (mut across, mut along_n) = (Vec3::zeros(), 0.0f32);
        for (i, hold) in holds.iter().flatten() {
            let Some(x) = now.get(*i) else {
                return;
            };
            let d = x - hold.place_mm;
            let d_along = t.dot(&d);
            across += (d - t * d_along) * hold.across_n_per_mm;
            along_n += d_along * hold.along_n_per_mm;
        }
        // Sliding, the tissue feels the friction's drag, no more: the damper standing for it in the solve is
        // stiff (the drag over a millimetre a second), and a thread flicked through it would pass the tissue
        // a pull that grows with the flick, and the tissue's answer would flick it back the next tick.
        if self.slip != 0.0 {
            along_n = along_n.clamp(-self.drag_n, self.drag_n);
        }
        let pull = across + t * along_n;
        // The capstan: the tensions either side (slack reads 0) and the angle the thread turns through at the
        // segment's two ends.
        let tension = |k: Option<usize>| {
            k.and_then(|k| tension_n.get(k))
                .map_or(0.0, |t: &f32| t.max(0.0))
        };
        // Beyond the held ends: segment s itself pulls where one end is not the hole's (the needle's tail).
        let behind_n = tension(if holds[0].is_some() {
            s.checked_sub(1)
        } else {
            Some(s)
        });
        let ahead_n = tension(Some(if holds[1].is_some() { s + 1 } else { s }));
        let turn = |a: Option<usize>, b: usize, c: usize| -> f32 {
            let (Some(a), Some(pb), Some(pc)) =
                (a.and_then(|a| now.get(a)), now.get(b), now.get(c))
            else {
                return 0.0;
            };
            (pb - a)
                .try_normalize(1e-9)
                .zip((pc - pb).try_normalize(1e-9))
                .map_or(0.0, |(n0, n1)| n0.dot(&n1).clamp(-1.0, 1.0).acos())
        };
        let turn_rad = turn(s.checked_sub(1), s, s + 1) + turn(Some(s), s + 1, s + 2);
        let wrap = (self.friction * turn_rad).exp();
        let (high_n, low_n) = (behind_n.max(ahead_n), behind_n.min(ahead_n));
        // What the hole holds back: the capstan's share of the lower tension, and the squeeze's.
        let drag_n = (wrap - 1.0) * low_n + self.friction * self.squeeze_n;
        if !(drag_n.is_finite() && high_n.is_finite() && pull.iter().all(|c| c.is_finite())) {
            return;
        }
        if self.slip == 0.0 {
            if high_n - low_n > drag_n {
                // It slides toward the higher tension: the nodes back along the thread when it is behind.
                self.slip = if behind_n > ahead_n { -1.0 } else { 1.0 };
                self.speed_mm_s = 0.0;
            }
        } else {
            let x = now[first];
            let u = first as f32 * segment_mm - t.dot(&(x - self.place_mm));
            self.speed_mm_s = (u - self.u_mm) / h_s;
            self.u_mm = u.max(0.0);
            if self.speed_mm_s.abs() < STOPPED_MM_S {
                self.slip = 0.0;
            } else {
                self.slip = -self.speed_mm_s.signum();
            }
        }
        self.drag_n = drag_n;
        // The thread's pull on the tissue is the springs' (the tissue's pull on the nodes, reversed).
        let magnitude = pull.norm();
        self.pull_sum_n += pull * (MAX_PULL_N / magnitude.max(MAX_PULL_N));
        self.substeps += 1;
        self.direction = t;
        self.across_n_per_mm = holds.iter().flatten().map(|(_, h)| h.across_n_per_mm).sum();
        self.along_n_per_mm = if self.slip == 0.0 {
            holds.iter().flatten().map(|(_, h)| h.along_n_per_mm).sum()
        } else {
            0.0
        };
    }
}

/// The arc length (rest lengths, mm) of the point of segments `k - 1 ..= k + 1` of the polyline `nodes` nearest
/// `to_mm`. None for a degenerate polyline.
fn nearest_arc_length(nodes: &[Vec3], k: usize, segment_mm: f32, to_mm: &Vec3) -> Option<f32> {
    let segments = nodes.len().checked_sub(1)?;
    let mut best: Option<(f32, f32)> = None;
    for s in k.saturating_sub(1)..(k + 2).min(segments) {
        let d = nodes[s + 1] - nodes[s];
        let len2 = d.norm_squared();
        if len2.is_nan() || len2 <= 1e-12 {
            continue;
        }
        let t = ((to_mm - nodes[s]).dot(&d) / len2).clamp(0.0, 1.0);
        let distance = (nodes[s] + d * t - to_mm).norm();
        if best.is_none_or(|(b, _)| distance < b) {
            best = Some((distance, (s as f32 + t) * segment_mm));
        }
    }
    best.map(|(_, u)| u)
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
        for hole in holes.iter_mut() {
            let held = hole.node_holds(
                &chain.positions_mm,
                chain.inverse_mass_per_kg(),
                2.0,
                0.00025,
            );
            for (i, hold) in held.into_iter().flatten() {
                assert!(chain.hold_node(i, hold));
            }
        }
        chain.step(0.00025, &Vec3::zeros(), 2);
        for hole in holes.iter_mut() {
            hole.after_substep(&chain.positions_mm, chain.tension_n(), 2.0, 0.00025);
        }
    }

    /// A free 40 mm thread (0.2 g a node: the drag is read before it has run through) along x through holes at
    /// `at_mm` along it (squeeze 1 N, `mu`), its far end pulled along +x with `pull_n` (ramped up over the first
    /// half) for `ticks` ms (no gravity): the first hole's arc length at the end, and the holes' summed mean
    /// pull on the tissue over the second half.
    fn pull_through(pull_n: f32, mu: f32, ticks: usize, at_mm: &[f32]) -> (f32, Vec3) {
        let nodes: Vec<Vec3> = (0..=20)
            .map(|i| Vec3::new(2.0 * i as f32, 0.0, 0.0))
            .collect();
        let mut chain = ThreadChain::new(&nodes, 2e-4, 1000.0, 5.0).unwrap();
        let mut holes: Vec<ThreadHole> = at_mm
            .iter()
            .map(|&u| hole_at(Vec3::new(u, 0.0, 0.0), u, 1.0, mu))
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
                chain.forces_n[20] = Vec3::new(pull_n * ramp, 0.0, 0.0);
                substep(&mut chain, &mut holes);
            }
            if tick >= ticks / 2 {
                pull_sum += holes.iter().map(|h| h.pull_on_tissue_n()).sum::<Vec3>();
            }
        }
        (holes[0].u_mm, pull_sum / (ticks - ticks / 2) as f32)
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
        // A non-finite thread: the hole holds nothing and pulls nothing.
        let mut broken = nodes.clone();
        broken[10] = Vec3::new(f32::NAN, 0.0, 0.0);
        let mut hole = hole_at(Vec3::new(20.0, 0.0, 0.0), 20.0, 1.0, 0.3);
        let w = vec![5e6; broken.len()];
        let held = hole.node_holds(&broken, &w, 2.0, 0.00025);
        let mut chain = ThreadChain::new(&nodes, 2e-7, 1000.0, 5.0).unwrap();
        let mut offered = 0;
        for (i, hold) in held.into_iter().flatten() {
            // A hold built on a non-finite node is refused by the chain.
            assert!(!chain.hold_node(i, hold), "{hold:?} was taken");
            offered += 1;
        }
        assert!(offered > 0, "the test meant the chain to refuse a hold");
        hole.after_substep(&broken, &[0.0; 20], 2.0, 0.00025);
        assert_eq!(hole.pull_on_tissue_n(), Vec3::zeros());
        assert!(hole.u_mm.is_finite());
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
        // Two nodes, each held by half the stiffness, across and (sticking) along.
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

//! The knot in a suture thread: what the thread's crossings tie, read from its shape alone.
//!
//! A stitch's thread is an open curve: its two ends (the needle's and the free one) leave the tissue and a
//! surgeon ties them around each other. Joined above the surgical field (each end straight up, then across;
//! and four ways tilted from up, the knot most of them read kept: [`KnotReader::read_thread`]), the thread
//! closes into a knot whose type is the knot the throws tied: one throw (a half knot) closes into a trefoil,
//! a square knot into a trefoil and its mirror image, a granny into two alike, a surgeon's double throw into
//! the (2, 5) torus knot. The reader projects the closed curve
//! (`knot/diagram.rs`), simplifies away kinks and strands merely lying on one another, computes the Jones
//! polynomial (`knot/bracket.rs`), which tells a knot from its mirror, and matches it against the products of
//! the throws' own polynomials (the Jones polynomial of a connected sum is the product of its parts'). A
//! thread lying in loops ties nothing, however many times it crosses itself.
//!
//! Owns: [`KnotReader`] (its buffers, and the last diagram it judged per closure, so an unchanged diagram is
//! not summed again), [`KnotKind`], [`Throws`]. Must not: allocate once its buffers have grown to the thread's
//! size.
//!
//! Not (yet): the throws' order (the polynomial of a sum does not carry it: right-left-right and
//! right-right-left read alike), a slip knot (the same topology as a square knot with one strand kept
//! straight), a knot's lock.

mod bracket;
mod diagram;
mod laurent;

use nalgebra::Vector3;

use crate::tissue::Vec3;
pub use bracket::MAX_BRACKET_CROSSINGS;
pub use diagram::DiagramError;
use diagram::{Diagram, Passage};
use laurent::Laurent;

/// The throws a knot is made of, by the knots they close into: a single throw (a trefoil) and a surgeon's
/// double throw (the (2, 5) torus knot), each right- or left-handed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Throws {
    /// Single throws closing into a right-handed trefoil.
    pub single_right: u8,
    /// Single throws closing into a left-handed trefoil.
    pub single_left: u8,
    /// Double throws closing into a right-handed (2, 5) torus knot.
    pub double_right: u8,
    /// Double throws closing into a left-handed (2, 5) torus knot.
    pub double_left: u8,
}

impl Throws {
    /// All the throws.
    pub fn count(&self) -> u8 {
        self.single_right + self.single_left + self.double_right + self.double_left
    }

    /// What a surgeon calls it: `half knot` (one throw), `square knot` (two single throws of opposite hands),
    /// `granny knot` (two of the same hand), `surgeon's knot` (a double throw, then a single one of the
    /// opposite hand), `surgeon's throw` (a double throw alone), else `N throws`.
    pub fn name(&self) -> String {
        let singles = self.single_right + self.single_left;
        let doubles = self.double_right + self.double_left;
        match (singles, doubles) {
            (1, 0) => "half knot".to_owned(),
            (0, 1) => "surgeon's throw".to_owned(),
            (2, 0) if self.single_right == 1 => "square knot".to_owned(),
            (2, 0) => "granny knot".to_owned(),
            (1, 1) if self.single_right == self.double_left => "surgeon's knot".to_owned(),
            _ => format!("{} throws", self.count()),
        }
    }

    /// Every pair of successive throws alternates hands where it can: as many right- as left-handed throws,
    /// give or take one (a square knot, a surgeon's knot, three throws right-left-right). The order is not
    /// read: this says only that such an order exists.
    pub fn can_alternate(&self) -> bool {
        let right = i32::from(self.single_right + self.double_right);
        let left = i32::from(self.single_left + self.double_left);
        (right - left).abs() <= 1
    }
}

/// What a thread ties.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KnotKind {
    /// No knot: the thread comes undone when its ends are drawn apart.
    #[default]
    None,
    /// A knot made of throws.
    Throws(Throws),
    /// A knot, but not one of throws (a figure-eight knot, say), with the crossings its diagram kept.
    Other {
        /// Crossings after simplification.
        crossings: u16,
    },
    /// Too tangled to judge: more crossings than the bracket sums ([`MAX_BRACKET_CROSSINGS`]) survive
    /// simplification.
    Tangled {
        /// Crossings after simplification.
        crossings: u16,
    },
}

/// A diagram judged: its signed Gauss code and the knot it was judged to be.
#[derive(Debug)]
struct Judged {
    code: Vec<Passage>,
    signs: Vec<i8>,
    kind: KnotKind,
}

/// Reads the knot in a thread. One per thread; keeps its buffers and its last judgement per closure.
#[derive(Debug)]
pub struct KnotReader {
    diagram: Diagram,
    closed: Vec<Vector3<f64>>,
    /// The last diagram judged and its judgement, one per closure ([`CLOSURES`], then one for
    /// [`KnotReader::read_closed`]).
    judged: [Judged; CLOSURES + 1],
    trefoil: Laurent,
    cinquefoil: Laurent,
}

impl Default for KnotReader {
    fn default() -> Self {
        Self::new()
    }
}

/// The Jones polynomial of the right-handed trefoil: `t + t^3 - t^4`.
fn trefoil_right() -> Laurent {
    Laurent::from_terms(&[(1, 1), (1, 3), (-1, 4)])
}

/// The Jones polynomial of the right-handed (2, 5) torus knot: `t^2 + t^4 - t^5 + t^6 - t^7`.
fn cinquefoil_right() -> Laurent {
    Laurent::from_terms(&[(1, 2), (1, 4), (-1, 5), (1, 6), (-1, 7)])
}

/// How far past the thread's furthest point a closure runs, mm.
const CLOSURE_CLEARANCE_MM: f64 = 20.0;
/// The ways an open thread is closed to be read ([`KnotReader::read_thread`]).
pub const CLOSURES: usize = 5;

impl KnotReader {
    /// A reader whose crossing buffers are sized for the most crossings a diagram keeps; its curve buffers
    /// grow at its first reading of a curve longer than any before.
    pub fn new() -> Self {
        Self {
            diagram: Diagram::new(),
            closed: Vec::new(),
            judged: std::array::from_fn(|_| Judged {
                code: Vec::with_capacity(2 * diagram::MAX_RAW_CROSSINGS),
                signs: Vec::with_capacity(diagram::MAX_RAW_CROSSINGS),
                kind: KnotKind::None,
            }),
            trefoil: trefoil_right(),
            cinquefoil: cinquefoil_right(),
        }
    }

    /// The knot tied by the open thread `nodes_mm` (needle end first, free end last, or the other way: the
    /// knot is the same), closed above the field in [`CLOSURES`] ways and judged by their vote.
    ///
    /// A closure takes each end along one direction to 20 mm past the thread's furthest point that way and
    /// joins the two there: straight up along `up_unit` (where the hands hold the ends), and tilted 60 degrees
    /// from it toward four sides. One closure alone reads a knot wrongly when a strand of it lies across the
    /// way out of an end (a loop flung up over the jaws holding the thread reads, closed straight up, as no
    /// knot); the others go out clear of it. The knot most closures read is the thread's (a tie goes to
    /// straight up, then to the first tilted).
    pub fn read_thread(
        &mut self,
        nodes_mm: &[Vec3],
        up_unit: Vec3,
    ) -> Result<KnotKind, DiagramError> {
        if nodes_mm.len() < 2 {
            return Err(DiagramError::BadCurve);
        }
        let up = up_unit.cast::<f64>().normalize();
        if !up.iter().all(|c| c.is_finite()) {
            return Err(DiagramError::BadCurve);
        }
        let (a, b) = across(up);
        let (cos, sin) = (0.5, 0.75f64.sqrt());
        let ways = [
            up,
            up * cos + a * sin,
            up * cos - a * sin,
            up * cos + b * sin,
            up * cos - b * sin,
        ];
        let mut votes = [(KnotKind::None, 0u8); CLOSURES];
        self.closed.clear();
        self.closed.extend(nodes_mm.iter().map(|p| p.cast::<f64>()));
        for (k, way) in ways.into_iter().enumerate() {
            self.close_along(nodes_mm.len(), way);
            let kind = self.judge_closed(view_from(way), k)?;
            votes[k] = (kind, 0);
            if let Some(v) = votes[..=k].iter_mut().find(|(seen, _)| *seen == kind) {
                v.1 += 1;
            }
        }
        // The first kind with the most votes (a kind's votes sit at its first reading).
        let mut chosen = votes[0];
        for v in &votes[1..] {
            if v.1 > chosen.1 {
                chosen = *v;
            }
        }
        Ok(chosen.0)
    }

    /// Close the open curve held in the first `n` points of the closed buffer along `way` (unit): each end
    /// taken along it to [`CLOSURE_CLEARANCE_MM`] past the curve's furthest point that way (what a last
    /// closure added is dropped first).
    fn close_along(&mut self, n: usize, way: Vector3<f64>) {
        self.closed.truncate(n);
        let top = self
            .closed
            .iter()
            .map(|p| p.dot(&way))
            .fold(f64::NEG_INFINITY, f64::max)
            + CLOSURE_CLEARANCE_MM;
        let first = self.closed[0];
        let last = self.closed[n - 1];
        self.closed.push(last + way * (top - last.dot(&way)));
        self.closed.push(first + way * (top - first.dot(&way)));
    }

    /// The knot of the closed polyline `points_mm` (the last point joins the first), seen along `up_unit`
    /// tilted a little (so no strand of a curve built on a grid lies edge-on).
    pub fn read_closed(
        &mut self,
        points_mm: &[Vector3<f64>],
        up_unit: Vector3<f64>,
    ) -> Result<KnotKind, DiagramError> {
        self.closed.clear();
        self.closed.extend_from_slice(points_mm);
        self.judge_closed(view_from(up_unit.normalize()), CLOSURES)
    }

    /// The diagram of the last reading, simplified: its crossings.
    pub fn crossings(&self) -> usize {
        self.diagram.crossings()
    }

    /// Projects the closed curve along `toward_viewer`, and along the [`VIEWS`] round it while the diagram
    /// keeps more crossings than the bracket sums, keeping the simplest; then judges that diagram (or returns
    /// the last judgement, if the diagram is the last one judged in `slot`: a closure's own).
    fn judge_closed(
        &mut self,
        toward_viewer: Vector3<f64>,
        slot: usize,
    ) -> Result<KnotKind, DiagramError> {
        self.diagram.project(&self.closed, toward_viewer)?;
        self.diagram.simplify();
        // The view the diagram holds, and the simplest so far (None: along `toward_viewer`).
        let (mut held, mut best_view, mut best) = (None, None, self.diagram.crossings());
        let (a, b) = across(toward_viewer);
        for (k, [x, y]) in VIEWS.iter().enumerate() {
            if best <= MAX_BRACKET_CROSSINGS / 2 {
                break;
            }
            let z = (1.0 - x * x - y * y).max(0.0).sqrt();
            self.diagram
                .project(&self.closed, toward_viewer * z + a * *x + b * *y)?;
            self.diagram.simplify();
            held = Some(k);
            if self.diagram.crossings() < best {
                (best_view, best) = (Some(k), self.diagram.crossings());
            }
        }
        // Projected again only when another view was tried after the simplest.
        if held != best_view {
            let view = best_view.map_or(toward_viewer, |k| {
                let [x, y] = VIEWS[k];
                toward_viewer * (1.0 - x * x - y * y).max(0.0).sqrt() + a * x + b * y
            });
            self.diagram.project(&self.closed, view)?;
            self.diagram.simplify();
        }
        let last = &mut self.judged[slot];
        if self.diagram.code() == last.code.as_slice()
            && self.diagram.signs() == last.signs.as_slice()
        {
            return Ok(last.kind);
        }
        let crossings = self.diagram.crossings() as u16;
        let kind = match bracket::jones(&self.diagram) {
            None => KnotKind::Tangled { crossings },
            Some(v) if v == Laurent::one() => KnotKind::None,
            Some(v) => self
                .match_throws(&v, crossings)
                .map_or(KnotKind::Other { crossings }, KnotKind::Throws),
        };
        let last = &mut self.judged[slot];
        last.code.clear();
        last.code.extend_from_slice(self.diagram.code());
        last.signs.clear();
        last.signs.extend_from_slice(self.diagram.signs());
        last.kind = kind;
        Ok(kind)
    }

    /// The throws whose polynomials multiply to `v`, trying every count that fits in `crossings` (a trefoil
    /// needs 3, a (2, 5) torus knot 5).
    fn match_throws(&self, v: &Laurent, crossings: u16) -> Option<Throws> {
        let parts = [
            self.trefoil,
            self.trefoil.mirrored(),
            self.cinquefoil,
            self.cinquefoil.mirrored(),
        ];
        let cost = [3u16, 3, 5, 5];
        let mut counts = [0u8; 4];
        search(v, &parts, &cost, crossings, 0, Laurent::one(), &mut counts).then_some(Throws {
            single_right: counts[0],
            single_left: counts[1],
            double_right: counts[2],
            double_left: counts[3],
        })
    }
}

/// Depth-first over the counts of `parts[from..]` (each costing `cost` crossings, within `budget`): true,
/// with `counts` set, when the product so far times them is `target`.
fn search(
    target: &Laurent,
    parts: &[Laurent; 4],
    cost: &[u16; 4],
    budget: u16,
    from: usize,
    product: Laurent,
    counts: &mut [u8; 4],
) -> bool {
    if from == parts.len() {
        return product == *target;
    }
    let mut p = product;
    let mut spent = 0u16;
    counts[from] = 0;
    loop {
        if search(target, parts, cost, budget - spent, from + 1, p, counts) {
            return true;
        }
        if spent + cost[from] > budget {
            break;
        }
        let Some(next) = p.mul(&parts[from]) else {
            break;
        };
        p = next;
        spent += cost[from];
        counts[from] += 1;
    }
    counts[from] = 0;
    false
}

/// The direction the reader looks from: `up`, tilted by about 7 degrees toward an arbitrary side.
fn view_from(up: Vector3<f64>) -> Vector3<f64> {
    let (a, b) = across(up);
    (up + a * 0.1093 + b * 0.0731).normalize()
}

/// Two unit vectors square to `d` and to each other.
fn across(d: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = helper.cross(&d).normalize();
    (a, d.cross(&a))
}

/// Other views tried when the first keeps too many crossings: the components across the first view of unit
/// directions spread over the half sphere in front of it (a golden-angle spiral, tilts 20 to 85 degrees).
const VIEWS: [[f64; 2]; 12] = [
    [0.342, 0.000],
    [-0.322, 0.295],
    [0.046, -0.525],
    [0.372, 0.486],
    [-0.680, -0.120],
    [0.642, -0.408],
    [-0.214, 0.795],
    [-0.405, -0.779],
    [0.866, 0.316],
    [-0.885, 0.365],
    [0.416, -0.889],
    [0.298, 0.951],
];

#[cfg(test)]
mod tests;

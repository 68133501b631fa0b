//! A closed polyline's knot diagram: its projection along a view direction, the crossings with their signs,
//! and the signed Gauss code (the crossings in the order the curve passes them, over or under), simplified by
//! Reidemeister moves I (a kink) and II (one strand lying across another).
//!
//! Owns: [`Diagram`] (the code and signs, in buffers kept between readings). Must not: allocate once its
//! buffers have grown to the thread's size, or read anything but the points it is given.

use nalgebra::{Vector2, Vector3};

/// One passage of the curve through a crossing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Passage {
    /// The crossing (an index into [`Diagram::signs`]).
    pub crossing: u16,
    /// The curve passes over (nearer the viewer) here.
    pub over: bool,
}

/// Why a polyline has no diagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagramError {
    /// Fewer than three points, or a point that is not finite.
    BadCurve,
    /// More crossings than the diagram keeps (before simplification).
    TooManyCrossings,
}

/// The most crossings a projection may have before simplification (a thread lying in loops on itself has a
/// few dozen at most).
pub const MAX_RAW_CROSSINGS: usize = 512;

/// A knot diagram as a signed Gauss code.
#[derive(Debug)]
pub struct Diagram {
    /// The passages in the order the curve meets them (each crossing twice: once over, once under).
    code: Vec<Passage>,
    /// Each crossing's sign: +1 right-handed, -1 left-handed (the over strand turned counterclockwise, seen
    /// from the viewer, meets the under strand within half a turn: +1).
    signs: Vec<i8>,
    /// Scratch: (curve parameter, passage) before sorting.
    raw: Vec<(f64, Passage)>,
    /// Scratch: crossing -> its two positions in the code.
    at: Vec<[u16; 2]>,
    /// Scratch: keep flags while simplifying.
    keep: Vec<bool>,
    /// Scratch: the projected points and their heights toward the viewer.
    flat: Vec<(Vector2<f64>, f64)>,
}

impl Default for Diagram {
    fn default() -> Self {
        Self::new()
    }
}

impl Diagram {
    /// An empty diagram (no crossing: the unknot's), its crossing buffers sized for [`MAX_RAW_CROSSINGS`]
    /// (so that no projection allocates but a longer curve's first).
    pub fn new() -> Self {
        Self {
            code: Vec::with_capacity(2 * MAX_RAW_CROSSINGS),
            signs: Vec::with_capacity(MAX_RAW_CROSSINGS),
            raw: Vec::with_capacity(2 * MAX_RAW_CROSSINGS),
            at: Vec::with_capacity(MAX_RAW_CROSSINGS),
            keep: Vec::with_capacity(2 * MAX_RAW_CROSSINGS),
            flat: Vec::new(),
        }
    }

    /// The signed Gauss code.
    pub fn code(&self) -> &[Passage] {
        &self.code
    }

    /// The crossings' signs, by crossing index.
    pub fn signs(&self) -> &[i8] {
        &self.signs
    }

    /// The number of crossings.
    pub fn crossings(&self) -> usize {
        self.code.len() / 2
    }

    /// The writhe: the sum of the crossings' signs.
    pub fn writhe(&self) -> i32 {
        self.signs.iter().map(|s| i32::from(*s)).sum()
    }

    /// Project the closed polyline `points` (the last point joins the first) along `toward_viewer_unit` (the
    /// viewer looks against it: the nearer of two strands at a crossing is over) and record its crossings.
    pub fn project(
        &mut self,
        points: &[Vector3<f64>],
        toward_viewer_unit: Vector3<f64>,
    ) -> Result<(), DiagramError> {
        self.code.clear();
        self.signs.clear();
        self.raw.clear();
        let n = points.len();
        if n < 3 || points.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(DiagramError::BadCurve);
        }
        let d = toward_viewer_unit.normalize();
        // e1 x e2 = d: counterclockwise in (e1, e2) is counterclockwise as the viewer sees it.
        let helper = if d.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = helper.cross(&d).normalize();
        let e2 = d.cross(&e1);
        self.flat.clear();
        self.flat.extend(
            points
                .iter()
                .map(|p| (Vector2::new(p.dot(&e1), p.dot(&e2)), p.dot(&d))),
        );
        let cross2 = |a: Vector2<f64>, b: Vector2<f64>| a.x * b.y - a.y * b.x;
        for i in 0..n {
            let (qi, hi) = self.flat[i];
            let (qi1, hi1) = self.flat[(i + 1) % n];
            let r = qi1 - qi;
            for j in i + 1..n {
                if j == i + 1 || (i == 0 && j == n - 1) {
                    continue; // neighbours share a point
                }
                let (qj, hj) = self.flat[j];
                let (qj1, hj1) = self.flat[(j + 1) % n];
                if qi.x.max(qi1.x) < qj.x.min(qj1.x)
                    || qj.x.max(qj1.x) < qi.x.min(qi1.x)
                    || qi.y.max(qi1.y) < qj.y.min(qj1.y)
                    || qj.y.max(qj1.y) < qi.y.min(qi1.y)
                {
                    continue;
                }
                let w = qj1 - qj;
                let denom = cross2(r, w);
                if denom.abs() < 1e-12 {
                    continue; // parallel in projection: no transverse crossing
                }
                let s = cross2(qj - qi, w) / denom;
                let t = cross2(qj - qi, r) / denom;
                // Half-open on each segment, so a crossing through a shared point counts once.
                if !((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t)) {
                    continue;
                }
                if self.signs.len() >= MAX_RAW_CROSSINGS {
                    return Err(DiagramError::TooManyCrossings);
                }
                let i_over = hi + s * (hi1 - hi) > hj + t * (hj1 - hj);
                let (over_dir, under_dir) = if i_over { (r, w) } else { (w, r) };
                let sign = if cross2(over_dir, under_dir) > 0.0 {
                    1
                } else {
                    -1
                };
                let c = self.signs.len() as u16;
                self.signs.push(sign);
                self.raw.push((
                    i as f64 + s,
                    Passage {
                        crossing: c,
                        over: i_over,
                    },
                ));
                self.raw.push((
                    j as f64 + t,
                    Passage {
                        crossing: c,
                        over: !i_over,
                    },
                ));
            }
        }
        self.raw.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        self.code.extend(self.raw.iter().map(|(_, p)| *p));
        Ok(())
    }

    /// Remove kinks (Reidemeister I: a crossing whose two passages follow each other) and strands lying
    /// across one another (Reidemeister II: two crossings met one after the other on both strands, the same
    /// strand over at both) until none is left, then number the crossings left from 0. The knot is unchanged.
    pub fn simplify(&mut self) {
        loop {
            let len = self.code.len();
            if len == 0 {
                break;
            }
            self.index_positions();
            self.keep.clear();
            self.keep.resize(len, true);
            let mut removed = false;
            for k in 0..len {
                let a = self.code[k];
                let next = (k + 1) % len;
                let b = self.code[next];
                if !self.keep[k] || !self.keep[next] {
                    continue;
                }
                if a.crossing == b.crossing {
                    // Reidemeister I.
                    self.keep[k] = false;
                    self.keep[next] = false;
                    removed = true;
                    break;
                }
                if a.over != b.over {
                    continue;
                }
                let other = |p: Passage, here: usize, at: &[[u16; 2]]| {
                    let [x, y] = at[p.crossing as usize];
                    if x as usize == here { y } else { x }
                };
                let (ao, bo) = (
                    other(a, k, &self.at) as usize,
                    other(b, next, &self.at) as usize,
                );
                if (ao + 1) % len == bo || (bo + 1) % len == ao {
                    // Reidemeister II.
                    for p in [k, next, ao, bo] {
                        self.keep[p] = false;
                    }
                    removed = true;
                    break;
                }
            }
            if !removed {
                break;
            }
            let mut w = 0;
            for r in 0..len {
                if self.keep[r] {
                    self.code[w] = self.code[r];
                    w += 1;
                }
            }
            self.code.truncate(w);
        }
        self.renumber();
    }

    /// `at[c]`: the two positions of crossing `c` in the code (crossings not in the code: unset).
    fn index_positions(&mut self) {
        self.at.clear();
        self.at.resize(self.signs.len(), [u16::MAX; 2]);
        for (k, p) in self.code.iter().enumerate() {
            let slot = &mut self.at[p.crossing as usize];
            if slot[0] == u16::MAX {
                slot[0] = k as u16;
            } else {
                slot[1] = k as u16;
            }
        }
    }

    /// Number the crossings left in the code 0.. in order of first passage, their signs with them.
    fn renumber(&mut self) {
        self.at.clear();
        self.at.resize(self.signs.len(), [u16::MAX; 2]);
        let mut next = 0u16;
        for k in 0..self.code.len() {
            let c = self.code[k].crossing as usize;
            if self.at[c][0] == u16::MAX {
                self.at[c][0] = next;
                // Signs are rewritten in place below: new index <= old index, and in first-passage order.
                next += 1;
            }
        }
        let mut new_signs = [0i8; MAX_RAW_CROSSINGS];
        for (old, slot) in self.at.iter().enumerate() {
            if slot[0] != u16::MAX {
                new_signs[slot[0] as usize] = self.signs[old];
            }
        }
        for p in self.code.iter_mut() {
            p.crossing = self.at[p.crossing as usize][0];
        }
        self.signs.clear();
        self.signs
            .extend_from_slice(&new_signs[..usize::from(next)]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A circle with one kink: a small loop that crosses the circle's own path once.
    fn kinked_circle() -> Vec<Vector3<f64>> {
        let mut points = Vec::new();
        for k in 0..40 {
            let a = std::f64::consts::TAU * f64::from(k) / 40.0;
            points.push(Vector3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0));
            if k == 10 {
                // Out past the circle, round a loop that crosses the outgoing stretch, and back.
                let base = Vector3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0);
                let out = Vector3::new(a.cos(), a.sin(), 0.0);
                let along = Vector3::new(-a.sin(), a.cos(), 0.0);
                points.push(base + out * 3.0 + along * 1.0 + Vector3::z() * 0.5);
                points.push(base + out * 4.0 - along * 1.0 + Vector3::z() * 0.5);
                points.push(base + out * 2.0 - along * 1.0 - Vector3::z() * 0.5);
                points.push(base + out * 2.0 + along * 2.0 - Vector3::z() * 0.5);
            }
        }
        points
    }

    #[test]
    fn a_kink_is_one_crossing_and_simplifies_away() {
        let mut d = Diagram::new();
        d.project(&kinked_circle(), Vector3::z()).unwrap();
        assert_eq!(d.crossings(), 1, "{:?}", d.code());
        d.simplify();
        assert_eq!(d.crossings(), 0);
        assert!(d.signs().is_empty());
    }

    #[test]
    fn a_strand_laid_across_another_simplifies_away() {
        // A long thin loop folded so its far end lies across its near part: two crossings, same strand over.
        let points: Vec<Vector3<f64>> = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(20.0, 0.0, 0.0),
            Vector3::new(20.0, 4.0, 0.0),
            Vector3::new(10.0, 4.0, 0.0),
            Vector3::new(10.0, -3.0, 1.0), // down across the bottom stretch, over it
            Vector3::new(5.0, -3.0, 1.0),
            Vector3::new(5.0, 6.0, 1.0), // back up across it, over again
            Vector3::new(0.0, 6.0, 0.0),
        ];
        let mut d = Diagram::new();
        d.project(&points, Vector3::z()).unwrap();
        assert_eq!(d.crossings(), 2, "{:?}", d.code());
        d.simplify();
        assert_eq!(d.crossings(), 0, "{:?}", d.code());
    }

    #[test]
    fn bad_curves_are_refused() {
        let mut d = Diagram::new();
        assert_eq!(
            d.project(&[Vector3::zeros(), Vector3::x()], Vector3::z()),
            Err(DiagramError::BadCurve)
        );
        let nan = [
            Vector3::zeros(),
            Vector3::x(),
            Vector3::new(f64::NAN, 0.0, 0.0),
        ];
        assert_eq!(d.project(&nan, Vector3::z()), Err(DiagramError::BadCurve));
    }
}

//! A material point (an element and its corners' weights) re-expressed after a subdivision: on the piece of its
//! element that holds it now, at the same place at rest.
//!
//! Owns: [`ElementRemap`]. A split puts each new vertex where the element's own interpolation puts that point,
//! so a point re-expressed on the piece holding it interpolates the same place now as before (to rounding); a
//! point on an element whose vertex moved onto a cut keeps its place at rest (the element's interpolation of it
//! now moves with the element's new shape). Must not: allocate, or panic on an element id it does not know
//! (that point is returned unchanged).

use super::*;

/// Re-expresses material points after a [`Subdivision`] of a model (the model as it is after it).
#[derive(Debug, Clone, Copy)]
pub struct ElementRemap<'a> {
    change: &'a Subdivision,
    model: &'a MassSpringModel,
}

/// Barycentric weights of `p` on triangle `[a, b, c]` (its projection onto the triangle's plane).
fn triangle_weights(p: &[f64; 3], [a, b, c]: [[f64; 3]; 3]) -> Option<[f64; 3]> {
    let sub = |x: &[f64; 3], y: &[f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: &[f64; 3], y: &[f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let (e0, e1, d) = (sub(&b, &a), sub(&c, &a), sub(p, &a));
    let (d00, d01, d11) = (dot(&e0, &e0), dot(&e0, &e1), dot(&e1, &e1));
    let (d20, d21) = (dot(&d, &e0), dot(&d, &e1));
    let det = d00 * d11 - d01 * d01;
    if det.abs() <= f64::EPSILON * d00 * d11 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / det;
    let w = (d00 * d21 - d01 * d20) / det;
    Some([1.0 - v - w, v, w])
}

/// Barycentric weights of `p` in tetrahedron `[a, b, c, d]`.
fn tet_weights(p: &[f64; 3], [a, b, c, d]: [[f64; 3]; 4]) -> Option<[f64; 4]> {
    let sub = |x: &[f64; 3], y: &[f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let cross = |x: &[f64; 3], y: &[f64; 3]| {
        [
            x[1] * y[2] - x[2] * y[1],
            x[2] * y[0] - x[0] * y[2],
            x[0] * y[1] - x[1] * y[0],
        ]
    };
    let dot = |x: &[f64; 3], y: &[f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let (e1, e2, e3, q) = (sub(&b, &a), sub(&c, &a), sub(&d, &a), sub(p, &a));
    let det = dot(&e1, &cross(&e2, &e3));
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let w1 = dot(&q, &cross(&e2, &e3)) / det;
    let w2 = dot(&e1, &cross(&q, &e3)) / det;
    let w3 = dot(&e1, &cross(&e2, &q)) / det;
    Some([1.0 - w1 - w2 - w3, w1, w2, w3])
}

/// Negative weights clamped to 0, the rest scaled to sum 1.
fn clamped<const K: usize>(w: [f64; K]) -> [f32; K] {
    let w = w.map(|x| x.max(0.0));
    let sum: f64 = w.iter().sum();
    if sum > 0.0 {
        w.map(|x| (x / sum) as f32)
    } else {
        [1.0 / K as f32; K]
    }
}

impl<'a> ElementRemap<'a> {
    /// Remap across `change`, `model` being the model after it.
    pub fn new(change: &'a Subdivision, model: &'a MassSpringModel) -> Self {
        Self { change, model }
    }

    /// Rest position of vertex `v` before the change.
    fn rest_before(&self, v: u32) -> [f64; 3] {
        let p = self
            .change
            .moved
            .iter()
            .find(|(m, _)| m.vertex == v)
            .map_or_else(
                || self.model.rest_positions_mm()[v as usize],
                |(_, from)| *from,
            );
        [p.x, p.y, p.z].map(f64::from)
    }

    /// Rest position of vertex `v` now.
    fn rest_now(&self, v: u32) -> [f64; 3] {
        let p = self.model.rest_positions_mm()[v as usize];
        [p.x, p.y, p.z].map(f64::from)
    }

    /// The rest point at `weights` of `corners` (before the change).
    fn point_before<const K: usize>(&self, corners: &[u32], weights: &[f32; K]) -> [f64; 3] {
        let mut p = [0.0f64; 3];
        for (&v, &w) in corners.iter().zip(weights) {
            let x = self.rest_before(v);
            for k in 0..3 {
                p[k] += f64::from(w) * x[k];
            }
        }
        p
    }

    /// Where a material point on surface triangle `triangle` at `weights` lies after the change: the piece of
    /// the triangle holding it and its weights there. Unchanged for a triangle the change did not touch.
    pub fn triangle(&self, triangle: u32, weights: [f32; 3]) -> (u32, [f32; 3]) {
        let volume = !self.model.tets().tets.is_empty();
        let (before, first, origins): (Option<[u32; 3]>, u32, &[u32]) = if volume {
            (
                self.change
                    .changed_triangles
                    .binary_search_by_key(&triangle, |&(t, _)| t)
                    .ok()
                    .map(|i| self.change.changed_triangles[i].1),
                self.change.first_new_triangle,
                &self.change.triangle_origins,
            )
        } else {
            (
                self.change
                    .changed_elements
                    .binary_search_by_key(&triangle, |&(t, _)| t)
                    .ok()
                    .map(|i| {
                        let c = self.change.changed_elements[i].1;
                        [c[0], c[1], c[2]]
                    }),
                self.change.first_new_element,
                &self.change.element_origins,
            )
        };
        let Some(before) = before else {
            return (triangle, weights);
        };
        let p = self.point_before(&before, &weights);
        let triangles = self.model.triangles();
        let candidates = std::iter::once(triangle).chain(
            origins
                .iter()
                .enumerate()
                .filter(|&(_, &o)| o == triangle)
                .map(|(k, _)| first + k as u32),
        );
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for t in candidates {
            let Some(corners) = triangles.get(t as usize) else {
                continue;
            };
            let Some(w) = triangle_weights(&p, corners.map(|v| self.rest_now(v))) else {
                continue;
            };
            let worst = w.iter().copied().fold(f64::INFINITY, f64::min);
            if best.is_none_or(|(b, _, _)| worst > b) {
                best = Some((worst, t, w));
            }
        }
        best.map_or((triangle, weights), |(_, t, w)| (t, clamped(w)))
    }

    /// Where a material point in tetrahedron `tet` at `weights` lies after the change: the piece holding it and
    /// its weights there. Unchanged for a tetrahedron the change did not touch.
    pub fn tet(&self, tet: u32, weights: [f32; 4]) -> (u32, [f32; 4]) {
        let Ok(i) = self
            .change
            .changed_elements
            .binary_search_by_key(&tet, |&(t, _)| t)
        else {
            return (tet, weights);
        };
        let before = self.change.changed_elements[i].1;
        if before[3] == NO_VERTEX {
            return (tet, weights);
        }
        let p = self.point_before(&before, &weights);
        let tets = &self.model.tets().tets;
        let first = self.change.first_new_element;
        let candidates = std::iter::once(tet).chain(
            self.change
                .element_origins
                .iter()
                .enumerate()
                .filter(|&(_, &o)| o == tet)
                .map(|(k, _)| first + k as u32),
        );
        let mut best: Option<(f64, u32, [f64; 4])> = None;
        for t in candidates {
            let Some(corners) = tets.get(t as usize) else {
                continue;
            };
            let Some(w) = tet_weights(&p, corners.map(|v| self.rest_now(v))) else {
                continue;
            };
            let worst = w.iter().copied().fold(f64::INFINITY, f64::min);
            if best.is_none_or(|(b, _, _)| worst > b) {
                best = Some((worst, t, w));
            }
        }
        best.map_or((tet, weights), |(_, t, w)| (t, clamped(w)))
    }
}

//! Blade sweeps and tears: which seams a cut or an overstretched spring opens.
//!
//! Owns: turning a sharp edge's motion over one tick into seams ([`swept_seams`]) and springs stretched past a
//! material's limit into seams ([`torn_seams`]). The opening itself, and what it does to ids, is
//! [`crate::tissue::seams`].
//!
//! A blade is a segment; between two ticks it sweeps a quadrilateral (its two ends then and now). Two elements
//! that share a facet are separated when the segment between their centroids (current positions) crosses that
//! quadrilateral: the facets so found form a chain along the blade's path, in the mesh's own facets. Where the
//! chain reaches the tissue's border, or crosses itself, the vertices on it split and the cut opens; where it
//! ends inside the tissue it leaves a crack tip, which the next tick's sweep extends. The crossing test is a
//! parry ray cast against the two triangles of the quadrilateral.
//!
//! Must not: change the model (it only reads positions), or allocate beyond its scratch's high-water mark.

use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::query::{Ray, RayCast};
use parry3d::shape::Triangle;

use super::BladePath;
use crate::collision::glam_boundary::to_parry;
use crate::tissue::seams::{Facet, facet_without, shared_by_two};
use crate::tissue::{MassSpringModel, Vec3};

/// A blade segment's ends at the start and at the end of a tick, world frame, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BladeSweep {
    /// The edge's two ends before.
    pub from_mm: [Vec3; 2],
    /// The edge's two ends after.
    pub to_mm: [Vec3; 2],
}

impl BladeSweep {
    /// The two triangles of the swept quadrilateral.
    pub(crate) fn triangles(&self) -> [Triangle; 2] {
        let [a, b] = self.from_mm.map(|p| to_parry(&p));
        let [c, d] = self.to_mm.map(|p| to_parry(&p));
        [Triangle::new(a, b, d), Triangle::new(a, d, c)]
    }

    /// The box around everything swept.
    pub(crate) fn aabb(&self) -> Aabb {
        let mut lo = self.from_mm[0];
        let mut hi = lo;
        for p in self.from_mm.iter().chain(&self.to_mm) {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Aabb::new(to_parry(&lo), to_parry(&hi))
    }

    /// Whether the blade moved at all.
    fn moved(&self) -> bool {
        self.from_mm != self.to_mm
    }
}

/// Scratch for [`swept_seams`], reused between ticks.
#[derive(Debug, Default)]
pub struct CutScratch {
    /// (facet, element) for the elements near the sweep.
    facets: Vec<(Facet, u32)>,
    /// The seams found this tick.
    pub seams: Vec<Facet>,
    /// The model whose longest spring `margin_mm` is (0: none yet).
    model_id: u64,
    /// How far beyond the swept box an element may reach and still have a centroid segment through it: the
    /// model's longest rest spring, twice (a stretched element).
    margin_mm: f32,
    /// The cut of a tissue that follows the blade (`cut = "follow-blade"`).
    pub path: BladePath,
}

impl CutScratch {
    /// How far beyond a sweep's box an element of `model` may reach and still be crossed by it: twice the
    /// model's longest rest spring (kept per model).
    pub(crate) fn margin_for(&mut self, model: &MassSpringModel) -> f32 {
        if self.model_id != model.id() {
            self.model_id = model.id();
            self.margin_mm = 2.0 * model.springs().rest_mm.iter().copied().fold(0.0, f32::max);
        }
        self.margin_mm
    }
}

/// Centroid of element `e` at `positions_mm`.
fn centroid<const K: usize>(element: &[u32; K], positions_mm: &[Vec3]) -> Vec3 {
    element
        .iter()
        .map(|&v| positions_mm[v as usize])
        .sum::<Vec3>()
        / K as f32
}

/// Whether the segment `p -> q` crosses either swept triangle.
fn crosses(swept: &[Triangle; 2], p: &Vec3, q: &Vec3) -> bool {
    let dir = q - p;
    if dir.norm_squared() == 0.0 {
        return false;
    }
    let ray = Ray::new(to_parry(p), to_parry(&dir));
    swept.iter().any(|t| t.intersects_local_ray(&ray, 1.0))
}

/// Push into `out` every seam the sweep opens among `elements` of `model` at `positions_mm`: `K` = 3 for a
/// sheet's triangles (seams are edges), 4 for a volume's tetrahedra (faces).
fn seams_among<const K: usize>(
    elements: &[[u32; K]],
    positions_mm: &[Vec3],
    sweep: &BladeSweep,
    scratch: &mut CutScratch,
    out: &mut Vec<Facet>,
) {
    let swept = sweep.triangles();
    let reach = sweep.aabb().loosened(scratch.margin_mm);
    scratch.facets.clear();
    for (e, element) in elements.iter().enumerate() {
        let mut lo = positions_mm[element[0] as usize];
        let mut hi = lo;
        for &v in &element[1..] {
            lo = lo.inf(&positions_mm[v as usize]);
            hi = hi.sup(&positions_mm[v as usize]);
        }
        if !reach.intersects(&Aabb::new(to_parry(&lo), to_parry(&hi))) {
            continue;
        }
        for skip in 0..K {
            scratch
                .facets
                .push((facet_without(element, skip), e as u32));
        }
    }
    scratch.facets.sort_unstable();
    for pair in scratch.facets.windows(2) {
        let [(fa, ea), (fb, eb)] = [pair[0], pair[1]];
        if fa != fb {
            continue;
        }
        let ca = centroid(&elements[ea as usize], positions_mm);
        let cb = centroid(&elements[eb as usize], positions_mm);
        if crosses(&swept, &ca, &cb) {
            out.push(fa);
        }
    }
}

/// The seams a blade sweep opens in `model` at `positions_mm`, appended to `out` (facets between two elements
/// near the sweep whose centroids it separates). Cost: one box test per element, then a sort of the facets of
/// the elements near the sweep (within twice the longest spring of it). No allocation beyond the scratch's
/// high-water mark.
pub fn swept_seams(
    model: &MassSpringModel,
    positions_mm: &[Vec3],
    sweep: &BladeSweep,
    scratch: &mut CutScratch,
    out: &mut Vec<Facet>,
) {
    if !sweep.moved() {
        return;
    }
    scratch.margin_for(model);
    let tets = &model.tets().tets;
    if tets.is_empty() {
        seams_among(model.triangles(), positions_mm, sweep, scratch, out);
    } else {
        seams_among(tets, positions_mm, sweep, scratch, out);
    }
}

/// The seams that springs stretched past `max_strain` (length over rest, minus one) open, appended to `out`.
/// A tear separates a spring's two ends: each element holding an overstretched spring (a sheet's triangle, a
/// volume's tetrahedron) is cut away from the rest of the ring of the spring's first end, along the element's
/// facet opposite the second end when another element shares it. The first end then splits, the spring's
/// elements hang from its copy, and the load the spring carried passes to its neighbours, which tear in turn:
/// the tear runs across the pull, and a band pulled past its limit parts. (A facet on the border has nothing to
/// separate.) No allocation beyond `out`'s capacity.
pub fn torn_seams(
    model: &MassSpringModel,
    positions_mm: &[Vec3],
    max_strain: f32,
    out: &mut Vec<Facet>,
) {
    if max_strain.is_nan() || max_strain <= 0.0 {
        return;
    }
    let springs = model.springs();
    let tets = &model.tets().tets;
    for s in 0..springs.len() {
        let (a, b, rest, _, _) = springs.get(s);
        if rest <= 0.0 {
            continue;
        }
        let strain = (positions_mm[b] - positions_mm[a]).norm() / rest - 1.0;
        if strain <= max_strain {
            continue;
        }
        let b = b as u32;
        if tets.is_empty() {
            for &t in model.node_triangles(a) {
                let triangle = &model.triangles()[t as usize];
                if let Some(k) = triangle.iter().position(|&v| v == b) {
                    push_if_shared(model, facet_without(triangle, k), out);
                }
            }
        } else {
            for &t in model.node_tets(a) {
                let tet = &tets[t as usize];
                if let Some(k) = tet.iter().position(|&v| v == b) {
                    push_if_shared(model, facet_without(tet, k), out);
                }
            }
        }
    }
}

/// Push `facet` when two elements share it.
fn push_if_shared(model: &MassSpringModel, facet: Facet, out: &mut Vec<Facet>) {
    if shared_by_two(model, &facet) {
        out.push(facet);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_through_the_swept_quad_crosses_it_and_one_beside_it_does_not() {
        let sweep = BladeSweep {
            from_mm: [Vec3::new(0.3, 0.0, -3.0), Vec3::new(0.3, 0.0, 3.0)],
            to_mm: [Vec3::new(0.3, 1.0, -3.0), Vec3::new(0.3, 1.0, 3.0)],
        };
        let swept = sweep.triangles();
        let (p, q) = (Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.6, 0.5, 0.0));
        assert!(crosses(&swept, &p, &q));
        assert!(crosses(&swept, &q, &p));
        let (p, q) = (Vec3::new(0.0, 1.5, 0.0), Vec3::new(0.6, 1.5, 0.0));
        assert!(!crosses(&swept, &p, &q));
        let (p, q) = (Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.2, 0.5, 0.0));
        assert!(!crosses(&swept, &p, &q));
    }
}

//! How well a sheet's marked circle was cut out: the measure FLS's pattern-cutting task is scored by (MISTELS:
//! "the percentage area of deviation from a perfect circle"), taken on the sheet at rest.
//!
//! Owns: [`PatternCircle`] (the two marked circles, the band the cut should run between), [`PatternCutReading`]
//! and [`read_pattern_cut`]. The sheet's pieces are its triangles joined by shared vertices (a cut's copies
//! split them); the **pattern's piece** is the piece of the triangles' vertex nearest the circles' centre at rest. It is
//! **freed** when it holds no fixed vertex (it came off the clipped sheet). The **deviation** is the area cut on
//! the wrong side of the band, at rest: the pattern's piece beyond the outer circle (cut too wide) plus the rest
//! of the sheet within the inner circle (cut into the pattern). A cut that runs inside the band deviates by
//! nothing, exactly: a triangle with every corner inside a circle lies inside it. Radii are 3-D distances from
//! the centre: the sheet is flat at rest, and the centre lies on it.
//!
//! Must not: allocate beyond the scratch it is given, or panic on any mesh.

use crate::tissue::Vec3;

/// Sub-triangles along each edge when a triangle straddles a circle: its area beyond the circle is counted by
/// the `SUBDIVISIONS^2` sub-triangles whose centroids lie beyond (on a 1 mm mesh, to about 0.1 mm of boundary).
const SUBDIVISIONS: usize = 10;

/// The two marked circles of a pattern, on a sheet at rest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatternCircle {
    /// Their common centre, rest frame of the sheet (world at rest), mm.
    pub centre_mm: Vec3,
    /// The inner circle's radius, mm.
    pub inner_radius_mm: f32,
    /// The outer circle's radius, mm (more than the inner's).
    pub outer_radius_mm: f32,
}

impl PatternCircle {
    /// The area of the pattern, mm^2: the disc of the band's middle radius (the circle to cut out).
    pub fn area_mm2(&self) -> f32 {
        let r = 0.5 * (self.inner_radius_mm + self.outer_radius_mm);
        std::f32::consts::PI * r * r
    }
}

/// How the cut stands now.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PatternCutReading {
    /// The pattern's piece came off the clipped sheet.
    pub freed: bool,
    /// Area of the pattern's piece beyond the outer circle, at rest, mm^2 (cut too wide).
    pub outside_band_mm2: f32,
    /// Area of the rest of the sheet within the inner circle, at rest, mm^2 (cut into the pattern).
    pub inside_band_mm2: f32,
    /// The pattern's area, mm^2 ([`PatternCircle::area_mm2`]).
    pub pattern_area_mm2: f32,
}

impl PatternCutReading {
    /// The deviation as a percentage of the pattern's area (the MISTELS penalty).
    pub fn deviation_pct(&self) -> f32 {
        if self.pattern_area_mm2 > 0.0 {
            100.0 * (self.outside_band_mm2 + self.inside_band_mm2) / self.pattern_area_mm2
        } else {
            0.0
        }
    }
}

/// Read the cut of `circle` on a sheet (`rest_mm` its rest positions, `triangles` its surface, `fixed(i)` true
/// for a clipped vertex). `pieces` is scratch (one entry per vertex). `None`: no triangle, or a triangle names a
/// vertex out of range.
pub fn read_pattern_cut(
    rest_mm: &[Vec3],
    triangles: &[[u32; 3]],
    fixed: impl Fn(usize) -> bool,
    circle: &PatternCircle,
    pieces: &mut Vec<u32>,
) -> Option<PatternCutReading> {
    let n = rest_mm.len();
    if triangles.iter().flatten().any(|&v| v as usize >= n) {
        return None;
    }
    let centre = circle.centre_mm;
    // The nearest vertex of a triangle (a vertex every triangle left is no piece of the sheet).
    let (nearest, _) = triangles
        .iter()
        .flatten()
        .map(|&v| (v as usize, (rest_mm[v as usize] - centre).norm_squared()))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    pieces.clear();
    pieces.extend(0..n as u32);
    for t in triangles {
        let a = root(pieces, t[0]);
        for &w in &t[1..] {
            let b = root(pieces, w);
            let (lo, hi) = (a.min(b), a.max(b));
            pieces[hi as usize] = lo;
        }
    }
    let pattern = root(pieces, nearest as u32);
    let freed = !(0..n).any(|i| fixed(i) && root(pieces, i as u32) == pattern);
    let (mut outside, mut inside) = (0.0_f32, 0.0_f32);
    for t in triangles {
        let corners = t.map(|v| rest_mm[v as usize]);
        if root(pieces, t[0]) == pattern {
            outside += area_beyond_mm2(&corners, &centre, circle.outer_radius_mm);
        } else {
            inside += triangle_area_mm2(&corners)
                - area_beyond_mm2(&corners, &centre, circle.inner_radius_mm);
        }
    }
    Some(PatternCutReading {
        freed,
        outside_band_mm2: outside,
        inside_band_mm2: inside.max(0.0),
        pattern_area_mm2: circle.area_mm2(),
    })
}

/// The root of `i`'s piece (path halving).
fn root(pieces: &mut [u32], mut i: u32) -> u32 {
    while pieces[i as usize] != i {
        let up = pieces[pieces[i as usize] as usize];
        pieces[i as usize] = up;
        i = up;
    }
    i
}

fn triangle_area_mm2([a, b, c]: &[Vec3; 3]) -> f32 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// The area of triangle `corners` farther than `radius_mm` from `centre`, mm^2: none when every corner lies
/// within (a ball is convex), all when the triangle lies wholly beyond (its nearest corner is farther than
/// the radius plus its longest edge), else counted by sub-triangles.
fn area_beyond_mm2(corners: &[Vec3; 3], centre: &Vec3, radius_mm: f32) -> f32 {
    let [a, b, c] = *corners;
    let distances = corners.map(|x| (x - centre).norm());
    if distances.iter().all(|&d| d <= radius_mm) {
        return 0.0;
    }
    let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
    let area = triangle_area_mm2(corners);
    if distances.iter().all(|&d| d > radius_mm + longest) {
        return area;
    }
    let m = SUBDIVISIONS as f32;
    let (u, v) = ((b - a) / m, (c - a) / m);
    let mut beyond = 0_usize;
    let r2 = radius_mm * radius_mm;
    for i in 0..SUBDIVISIONS {
        for j in 0..SUBDIVISIONS - i {
            let (fi, fj) = (i as f32, j as f32);
            let up = a + u * (fi + 1.0 / 3.0) + v * (fj + 1.0 / 3.0);
            beyond += usize::from((up - centre).norm_squared() > r2);
            if i + j + 1 < SUBDIVISIONS {
                let down = a + u * (fi + 2.0 / 3.0) + v * (fj + 2.0 / 3.0);
                beyond += usize::from((down - centre).norm_squared() > r2);
            }
        }
    }
    // All or none: exactly the triangle's area or nothing (the share would round).
    match beyond {
        0 => 0.0,
        all if all == SUBDIVISIONS * SUBDIVISIONS => area,
        some => area * some as f32 / (SUBDIVISIONS * SUBDIVISIONS) as f32,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A flat square grid of `cells` x `cells` cells of `size_mm`, centred on the origin in the x-y plane, its
    /// border vertices fixed; and, when `cut_radius_mm` is given, every triangle whose centroid lies within it
    /// re-pointed at copies of its vertices (a disc cut out along the mesh's own edges).
    fn grid(
        cells: usize,
        size_mm: f32,
        cut_radius_mm: Option<f32>,
    ) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<bool>) {
        let w = cells + 1;
        let half = 0.5 * cells as f32 * size_mm;
        let mut rest: Vec<Vec3> = (0..w * w)
            .map(|k| {
                Vec3::new(
                    (k % w) as f32 * size_mm - half,
                    (k / w) as f32 * size_mm - half,
                    0.0,
                )
            })
            .collect();
        let mut fixed: Vec<bool> = (0..w * w)
            .map(|k| k % w == 0 || k % w == cells || k / w == 0 || k / w == cells)
            .collect();
        let mut triangles = Vec::new();
        for j in 0..cells {
            for i in 0..cells {
                let k = (j * w + i) as u32;
                let w = w as u32;
                triangles.push([k, k + 1, k + w + 1]);
                triangles.push([k, k + w + 1, k + w]);
            }
        }
        if let Some(r) = cut_radius_mm {
            let mut copy = vec![None; rest.len()];
            for t in &mut triangles {
                let centroid = t.iter().map(|&v| rest[v as usize]).sum::<Vec3>() / 3.0;
                if centroid.norm() < r {
                    for v in t.iter_mut() {
                        let c = *copy[*v as usize].get_or_insert_with(|| {
                            rest.push(rest[*v as usize]);
                            fixed.push(false);
                            rest.len() as u32 - 1
                        });
                        *v = c;
                    }
                }
            }
        }
        (rest, triangles, fixed)
    }

    fn read(cut: Option<f32>, inner: f32, outer: f32) -> PatternCutReading {
        let (rest, triangles, fixed) = grid(40, 1.0, cut);
        let circle = PatternCircle {
            centre_mm: Vec3::zeros(),
            inner_radius_mm: inner,
            outer_radius_mm: outer,
        };
        read_pattern_cut(&rest, &triangles, |i| fixed[i], &circle, &mut Vec::new()).unwrap()
    }

    #[test]
    fn an_uncut_sheet_is_not_freed_and_all_of_it_beyond_the_outer_circle_deviates() {
        let r = read(None, 8.0, 10.0);
        assert!(!r.freed);
        // The pattern's piece is the whole sheet: all of it beyond the outer circle is cut too wide.
        let beyond = 1600.0 - std::f32::consts::PI * 100.0;
        assert!(
            (r.outside_band_mm2 - beyond).abs() < 0.01 * beyond,
            "outside {}",
            r.outside_band_mm2
        );
        assert_eq!(r.inside_band_mm2, 0.0);
    }

    #[test]
    fn a_disc_cut_inside_the_band_is_freed_with_no_deviation_and_one_cut_too_small_deviates_by_the_ring_left()
     {
        // Cut along the grid's edges at about 9 mm: a staircase between 8 and 10 mm.
        let clean = read(Some(9.0), 7.5, 10.5);
        assert!(clean.freed);
        assert_eq!(clean.outside_band_mm2 + clean.inside_band_mm2, 0.0);
        // The same cut judged against a band of 10-12 mm: the ring between the staircase and 10 mm is left.
        let small = read(Some(9.0), 10.0, 12.0);
        assert!(small.freed);
        assert_eq!(small.outside_band_mm2, 0.0);
        let disc_cut: f32 = {
            let (rest, triangles, _) = grid(40, 1.0, Some(9.0));
            let first_copy = 41 * 41;
            triangles
                .iter()
                .filter(|t| t[0] as usize >= first_copy)
                .map(|t| triangle_area_mm2(&t.map(|v| rest[v as usize])))
                .sum()
        };
        let expected = std::f32::consts::PI * 100.0 - disc_cut;
        assert!(
            (small.inside_band_mm2 - expected).abs() < 0.03 * expected,
            "inside {} against {expected}",
            small.inside_band_mm2
        );
        assert!(small.deviation_pct() > 0.0);
    }

    #[test]
    fn a_triangle_beyond_and_one_straddling_a_circle_count_what_lies_beyond() {
        let t = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
        ];
        let far = Vec3::new(100.0, 0.0, 0.0);
        assert_eq!(area_beyond_mm2(&t, &far, 1.0), 8.0);
        assert_eq!(area_beyond_mm2(&t, &Vec3::zeros(), 10.0), 0.0);
        // A quarter disc of radius 2 at the right-angle corner: 8 - pi.
        let beyond = area_beyond_mm2(&t, &Vec3::zeros(), 2.0);
        assert!(
            (beyond - (8.0 - std::f32::consts::PI)).abs() < 0.15,
            "{beyond}"
        );
    }

    #[test]
    fn a_triangle_naming_a_missing_vertex_reads_nothing() {
        let circle = PatternCircle {
            centre_mm: Vec3::zeros(),
            inner_radius_mm: 1.0,
            outer_radius_mm: 2.0,
        };
        let rest = [Vec3::zeros(), Vec3::x(), Vec3::y()];
        assert!(
            read_pattern_cut(&rest, &[[0, 1, 3]], |_| false, &circle, &mut Vec::new()).is_none()
        );
        assert!(read_pattern_cut(&[], &[], |_| false, &circle, &mut Vec::new()).is_none());
    }
}

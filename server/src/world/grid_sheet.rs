//! A flat rectangular sheet of triangles on z = 0, centred on the origin: the pad's mesh, and the sheets the
//! tests and benchmarks build. Owns the grid layout and its OBJ text; build-time only (allocates).

use std::fmt::Write as _;

use super::SurfaceMesh;

/// `nx` x `ny` cells of `cell_mm`, two triangles per cell with the diagonal alternating from cell to cell (no
/// preferred shear direction), wound so the normals point along +z. Node `j * (nx + 1) + i` sits at column
/// `i`, row `j`.
pub fn grid_sheet(nx: usize, ny: usize, cell_mm: f32) -> SurfaceMesh {
    let (x0, y0) = (-(nx as f32) * cell_mm / 2.0, -(ny as f32) * cell_mm / 2.0);
    let mut positions_mm = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            positions_mm.push([x0 + i as f32 * cell_mm, y0 + j as f32 * cell_mm, 0.0]);
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    SurfaceMesh {
        positions_mm,
        triangles,
    }
}

/// The mesh as Wavefront OBJ text (1-based faces), after `header` lines (comments, an `o` line).
pub fn to_obj_text(mesh: &SurfaceMesh, header: &[&str]) -> String {
    let mut text = String::with_capacity(mesh.positions_mm.len() * 24 + mesh.triangles.len() * 20);
    for line in header {
        text.push_str(line);
        text.push('\n');
    }
    for p in &mesh.positions_mm {
        let _ = writeln!(text, "v {} {} {}", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        let _ = writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::validate_surface;

    #[test]
    fn a_sheet_is_a_valid_upward_surface_with_the_expected_counts() {
        let sheet = grid_sheet(4, 3, 2.0);
        assert_eq!((sheet.positions_mm.len(), sheet.triangles.len()), (20, 24));
        validate_surface(&sheet).unwrap();
        for t in &sheet.triangles {
            let [a, b, c] = t.map(|v| sheet.positions_mm[v as usize]);
            let cross_z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(cross_z > 0.0, "triangle {t:?} faces down");
        }
        assert_eq!(sheet.positions_mm[0], [-4.0, -3.0, 0.0]);
        let text = to_obj_text(&sheet, &["o sheet"]);
        assert!(text.starts_with("o sheet\nv -4 -3 0\n") && text.ends_with("f 15 20 19\n"));
    }
}

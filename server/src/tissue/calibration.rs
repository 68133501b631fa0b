//! Spring constants from Young's modulus and Poisson's ratio: calibrated mass-spring tissue.
//!
//! Owns: the per-element fit of spring stiffnesses to a linear elastic element, for tetrahedra and for
//! triangles (a sheet of given thickness). Must not: know about the world file or time stepping.
//!
//! The method is Lloyd, Székely and Harders' ("Identification of spring parameters for deformable object
//! simulation", IEEE TVCG 13(5), 2007): make each element's spring stiffness matrix `sum_e k_e u_e u_e^T`
//! (`u_e` the unit stretch of edge `e`: `+n` at one end, `-n` at the other) as close as possible to the
//! linear finite element's `K = V B^T D B`. They solve it in closed form for particular shapes; here it is
//! the least-squares problem in the Frobenius norm, solved per element for any shape: `G k = r` with
//! `G_ef = (u_e . u_f)^2` and `r_e = u_e^T K u_e` (the element's strain energy for that stretch), negative
//! results clamped to zero, and each edge summing what its elements give it.
//!
//! Poisson's ratio. A network of central springs obeys the Cauchy relation, `lambda = mu`: a tetrahedral
//! network has `nu = 1/4` and a triangle sheet `nu = 1/3` whatever its constants (Lloyd et al. section 4;
//! Golec, Palierne, Zara, Nicolle and Damiand, "Hybrid 3D mass-spring system for simulation of isotropic
//! materials with any Poisson's ratio", The Visual Computer 36, 2020). So the springs are fitted to the
//! shear modulus `mu` with `nu = 1/4` (tetrahedra), and, as Golec et al. do, a volume energy that ignores
//! shape supplies the rest of the first Lamé parameter: the per-tetrahedron volume term with bulk modulus
//! `lambda - mu` ([`volume_supplement_n_per_mm2`]), which needs `nu >= 1/4`. A sheet has no volume, so its
//! springs are fitted with `nu = 1/3` and that is the only ratio it can have.

use nalgebra::{DMatrix, DVector, Matrix3};

use super::Vec3;

/// The Poisson's ratio a tetrahedral spring network has (the Cauchy relation).
pub const TET_NETWORK_POISSON: f32 = 0.25;

/// The Poisson's ratio a triangle spring sheet has.
pub const SHEET_NETWORK_POISSON: f32 = 1.0 / 3.0;

/// The six edges of a tetrahedron, as vertex pairs (the order of [`tet_spring_constants`]' result).
pub const TET_EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The three edges of a triangle (the order of [`triangle_spring_constants`]' result).
pub const TRIANGLE_EDGES: [(usize, usize); 3] = [(0, 1), (1, 2), (0, 2)];

/// Shear modulus, N/mm^2.
fn shear(youngs_n_per_mm2: f32, poisson: f32) -> f32 {
    youngs_n_per_mm2 / (2.0 * (1.0 + poisson))
}

/// The bulk modulus of the volume term that brings a tetrahedral spring network (which has `lambda = mu`) to
/// Poisson's ratio `poisson`: `lambda - mu`, N/mm^2 (0 at `nu = 1/4`; negative below, which the loader
/// refuses).
pub fn volume_supplement_n_per_mm2(youngs_n_per_mm2: f32, poisson: f32) -> f32 {
    let mu = shear(youngs_n_per_mm2, poisson);
    let lambda = youngs_n_per_mm2 * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    lambda - mu
}

/// Least-squares spring constants (N/mm) for an element with shape gradients `b` (one per vertex), measure
/// `size` (volume, or area times thickness), Lamé parameters `mu`, `lambda` and the given edges.
fn fit<const E: usize, const V: usize>(
    x: [Vec3; V],
    b: [Vec3; V],
    size: f32,
    mu: f32,
    lambda: f32,
    edges: [(usize, usize); E],
) -> [f32; E] {
    let dirs: [Vec3; E] = edges.map(|(i, j)| {
        (x[j] - x[i])
            .try_normalize(1e-12)
            .unwrap_or_else(Vec3::zeros)
    });
    // Build time only (a small dense solve per element): allocation is fine here.
    let mut g = DMatrix::<f64>::zeros(E, E);
    let mut r = DVector::<f64>::zeros(E);
    for (e, &(i, j)) in edges.iter().enumerate() {
        // The edge's unit stretch: +n at j, -n at i; its strain is sym(n (b_j - b_i)^T).
        let n = dirs[e];
        let grad = n * (b[j] - b[i]).transpose();
        let strain: Matrix3<f32> = (grad + grad.transpose()) * 0.5;
        let energy = size * (2.0 * mu * strain.norm_squared() + lambda * strain.trace().powi(2));
        r[e] = f64::from(energy);
        for (f, &(p, q)) in edges.iter().enumerate() {
            let shared = |a: usize| {
                if a == i {
                    -1.0
                } else if a == j {
                    1.0
                } else {
                    0.0
                }
            };
            // u_e . u_f = sum over shared vertices of (sign_e n_e) . (sign_f n_f).
            let dot = (shared(q) - shared(p)) * dirs[f].dot(&n);
            g[(e, f)] = f64::from(dot * dot);
        }
    }
    let k = g.lu().solve(&r).unwrap_or_else(|| DVector::zeros(E));
    std::array::from_fn(|e| (k[e] as f32).max(0.0))
}

/// Spring constants (N/mm, in [`TET_EDGES`] order) fitted to a linear tetrahedron with shear modulus `mu` and
/// the network's own `lambda = mu`, the element at rest positions `x`.
pub fn tet_spring_constants(x: [Vec3; 4], shear_n_per_mm2: f32) -> [f32; 6] {
    let dm = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
    let volume = dm.determinant().abs() / 6.0;
    let Some(inverse) = dm.try_inverse() else {
        return [0.0; 6];
    };
    let rows: [Vec3; 3] = std::array::from_fn(|k| inverse.row(k).transpose());
    let b = [-(rows[0] + rows[1] + rows[2]), rows[0], rows[1], rows[2]];
    fit(x, b, volume, shear_n_per_mm2, shear_n_per_mm2, TET_EDGES)
}

/// Spring constants (N/mm, in [`TRIANGLE_EDGES`] order) fitted to a plane-stress triangle of thickness
/// `thickness_mm` with Young's modulus `youngs_n_per_mm2` and the sheet network's own `nu = 1/3`.
pub fn triangle_spring_constants(
    x: [Vec3; 3],
    youngs_n_per_mm2: f32,
    thickness_mm: f32,
) -> [f32; 3] {
    let normal = (x[1] - x[0]).cross(&(x[2] - x[0]));
    let twice_area = normal.norm();
    if twice_area <= 1e-12 {
        return [0.0; 3];
    }
    let n = normal / twice_area;
    let b: [Vec3; 3] =
        std::array::from_fn(|k| n.cross(&(x[(k + 2) % 3] - x[(k + 1) % 3])) / twice_area);
    let nu = SHEET_NETWORK_POISSON;
    let mu = shear(youngs_n_per_mm2, nu);
    let lambda_plane_stress = youngs_n_per_mm2 * nu / (1.0 - nu * nu);
    fit(
        x,
        b,
        0.5 * twice_area * thickness_mm,
        mu,
        lambda_plane_stress,
        TRIANGLE_EDGES,
    )
}

/// Stiffness of every edge (N/mm, same order as `edges`, which must be sorted with `a < b`), summed over the
/// elements that hold it: the tetrahedra when there are any (a volume), else the triangles of a sheet of
/// `thickness_mm`. An edge on no element gets 0. Build time only (allocates nothing per edge beyond the result).
pub fn calibrated_edge_stiffness(
    rest_mm: &[Vec3],
    edges: &[[u32; 2]],
    tets: &[[u32; 4]],
    triangles: &[[u32; 3]],
    youngs_n_per_mm2: f32,
    poisson: f32,
    thickness_mm: f32,
) -> Vec<f32> {
    let mut stiffness = vec![0.0f32; edges.len()];
    let mut add = |p: u32, q: u32, k: f32| {
        if let Ok(e) = edges.binary_search(&[p.min(q), p.max(q)]) {
            stiffness[e] += k;
        }
    };
    if !tets.is_empty() {
        let mu = shear(youngs_n_per_mm2, poisson);
        for tet in tets {
            let k = tet_spring_constants(tet.map(|i| rest_mm[i as usize]), mu);
            for (e, &(i, j)) in TET_EDGES.iter().enumerate() {
                add(tet[i], tet[j], k[e]);
            }
        }
    } else {
        for tri in triangles {
            let k = triangle_spring_constants(
                tri.map(|i| rest_mm[i as usize]),
                youngs_n_per_mm2,
                thickness_mm,
            );
            for (e, &(i, j)) in TRIANGLE_EDGES.iter().enumerate() {
                add(tri[i], tri[j], k[e]);
            }
        }
    }
    stiffness
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_equilateral_triangle_gets_lloyds_constant() {
        // Lloyd et al.: k = sqrt(3) / 4 E t on every edge of an equilateral triangle (nu = 1/3).
        let x = [
            Vec3::zeros(),
            Vec3::x(),
            Vec3::new(0.5, 3f32.sqrt() / 2.0, 0.0),
        ];
        let k = triangle_spring_constants(x, 2.0, 0.5);
        let expected = 3f32.sqrt() / 4.0 * 2.0 * 0.5;
        for ke in k {
            assert!(
                (ke - expected).abs() < 1e-4 * expected,
                "{k:?} vs {expected}"
            );
        }
    }

    #[test]
    fn a_regular_tetrahedron_gets_equal_constants_that_scale_with_size() {
        let x = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let k = tet_spring_constants(x, 1.0);
        assert!(
            k.iter()
                .all(|&ke| (ke - k[0]).abs() < 1e-4 * k[0] && ke > 0.0),
            "{k:?}"
        );
        let doubled = tet_spring_constants(x.map(|p| p * 2.0), 1.0);
        assert!((doubled[0] - 2.0 * k[0]).abs() < 1e-4 * k[0]);
        // At nu = 1/4 no volume term is needed; at 0.45 it is 8 mu.
        assert!(volume_supplement_n_per_mm2(2.5, 0.25).abs() < 1e-6);
        let mu = 1.0 / 2.9;
        assert!((volume_supplement_n_per_mm2(1.0, 0.45) - 8.0 * mu).abs() < 1e-4);
    }
}

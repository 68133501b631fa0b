//! The corotational elements' deviatoric stiffness assembled on the mesh's edges once per implicit step, so
//! each conjugate-gradient iteration multiplies by a sparse block matrix instead of re-deriving every element.
//!
//! Owns: [`AssembledStiffness`]: per node a 3x3 diagonal block and per edge a 3x3 off-diagonal block of
//! `sum_e R_e K_e R_e^T` (elements' rotations frozen at the step's start), the map from each element's six
//! edges to the model's edge list, and the block product. Element `e`'s block between its nodes `i` and `j` is
//! `R K_ij R^T` with `K_ij = mu V0 [(b_i . b_j) I + b_j b_i^T - 2/3 b_i b_j^T]` (`b` the shape gradients),
//! written with `c = R b` as `mu V0 [(b_i . b_j) I + c_j c_i^T - 2/3 c_i c_j^T]`: the same operator
//! [`super::fem::element_deviatoric_product`] applies element by element (a test checks them against each
//! other). A product then costs about 27 multiply-adds per tetrahedron (1.4 edges and 0.23 nodes each) against
//! about 170 for the element-wise product, and the assembly about as much as two element-wise products.
//!
//! Must not: hold the nodal volume term (it couples two rings of nodes, not edges: it stays matrix-free in
//! [`FemElements::add_volume_product`]).

use nalgebra::Matrix3;

use super::Vec3;
use super::fem::{FemElements, FemLinearization, shape_gradient};
use super::volume::TetVolumes;

/// Set on an element-edge code when the element's pair runs against the edge's `(a, b)` order.
const FLIP: u32 = 1 << 31;
/// An element's six edges, as pairs of its corners.
const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The assembled deviatoric stiffness of one model, rebuilt every step; reusable scratch.
#[derive(Debug, Clone, Default)]
pub struct AssembledStiffness {
    /// Per element, its six edges' indices in the model's edge list (with [`FLIP`]).
    tet_edges: Vec<[u32; 6]>,
    /// Scratch of the map's build: `(min << 32 | max, edge)`, sorted.
    keys: Vec<(u64, u32)>,
    /// Per edge `e`, the block acting on `p[b[e]]` into `out[a[e]]` (its transpose goes the other way), N/mm.
    edge_blocks: Vec<Matrix3<f32>>,
    /// Per node, its diagonal block, N/mm.
    node_blocks: Vec<Matrix3<f32>>,
    /// The blocks hold this step's stiffness.
    ready: bool,
}

fn key(i: u32, j: u32) -> u64 {
    (u64::from(i.min(j)) << 32) | u64::from(i.max(j))
}

impl AssembledStiffness {
    /// Assemble `fem`'s deviatoric stiffness, rotations frozen in `lin`, onto the `nodes` nodes and the edges
    /// `(a[k], b[k])`. Returns false, and leaves [`Self::add_product`] adding nothing, when the model has no
    /// elements or an element's edge is not among the edges (the caller then uses the element-wise product).
    /// Allocates only when the mesh changed since the last call (its map is rebuilt) or grew; never panics.
    pub fn assemble(
        &mut self,
        fem: &FemElements,
        tets: &TetVolumes,
        lin: &FemLinearization,
        a: &[u32],
        b: &[u32],
        nodes: usize,
    ) -> bool {
        self.ready = false;
        let rotations = lin.rotations();
        if !fem.is_on()
            || rotations.len() != tets.tets.len()
            || a.len() != b.len()
            || a.iter().chain(b).any(|&i| i as usize >= nodes)
        {
            return false;
        }
        if !self.map_matches(tets, a, b) && !self.rebuild_map(tets, a, b) {
            return false;
        }
        self.edge_blocks.clear();
        self.edge_blocks.resize(a.len(), Matrix3::zeros());
        self.node_blocks.clear();
        self.node_blocks.resize(nodes, Matrix3::zeros());
        let mu = fem.shear_modulus_n_per_mm2();
        for (t, tet) in tets.tets.iter().enumerate() {
            let inverse = fem.rest_inverse(t);
            let r = &rotations[t];
            let gradients: [Vec3; 4] = std::array::from_fn(|k| shape_gradient(&inverse, k));
            let rotated = gradients.map(|g| r * g);
            let w = mu * tets.rest_volume_mm3[t];
            let block = |i: usize, j: usize| -> Matrix3<f32> {
                (Matrix3::from_diagonal_element(gradients[i].dot(&gradients[j]))
                    + rotated[j] * rotated[i].transpose()
                    - rotated[i] * rotated[j].transpose() * (2.0 / 3.0))
                    * w
            };
            for (k, &node) in tet.iter().enumerate() {
                if let Some(n) = self.node_blocks.get_mut(node as usize) {
                    *n += block(k, k);
                }
            }
            for (pair, &(i, j)) in PAIRS.iter().enumerate() {
                let code = self.tet_edges[t][pair];
                let m = block(i, j);
                if let Some(edge) = self.edge_blocks.get_mut((code & !FLIP) as usize) {
                    *edge += if code & FLIP == 0 { m } else { m.transpose() };
                }
            }
        }
        self.ready = true;
        true
    }

    /// The last [`Self::assemble`] succeeded: [`Self::add_product`] holds this step's deviatoric stiffness.
    pub fn is_ready(&self) -> bool {
        self.ready
    }

    /// `out += scale K_dev p` with the blocks of the last [`Self::assemble`] on the same edges (nothing if it
    /// failed, or if the slices do not match its node count). No allocation.
    pub fn add_product(&self, a: &[u32], b: &[u32], p: &[Vec3], scale: f32, out: &mut [Vec3]) {
        let nodes = self.node_blocks.len();
        if !self.ready
            || p.len() != nodes
            || out.len() != nodes
            || a.len() != self.edge_blocks.len()
        {
            return;
        }
        for ((o, m), q) in out.iter_mut().zip(&self.node_blocks).zip(p) {
            *o += (m * q) * scale;
        }
        // Every index was checked against `nodes` when the blocks were assembled.
        for ((m, &i), &j) in self.edge_blocks.iter().zip(a).zip(b) {
            let (i, j) = (i as usize, j as usize);
            out[i] += (m * p[j]) * scale;
            out[j] += m.tr_mul(&p[i]) * scale;
        }
    }

    /// The element-edge map still describes `tets` on these edges (12 comparisons an element).
    fn map_matches(&self, tets: &TetVolumes, a: &[u32], b: &[u32]) -> bool {
        self.tet_edges.len() == tets.tets.len()
            && tets.tets.iter().zip(&self.tet_edges).all(|(tet, codes)| {
                PAIRS.iter().zip(codes).all(|(&(i, j), &code)| {
                    let e = (code & !FLIP) as usize;
                    let (from, to) = if code & FLIP == 0 {
                        (tet[i], tet[j])
                    } else {
                        (tet[j], tet[i])
                    };
                    a.get(e) == Some(&from) && b.get(e) == Some(&to)
                })
            })
    }

    /// Map every element's edges to the edge list; false if one is missing.
    fn rebuild_map(&mut self, tets: &TetVolumes, a: &[u32], b: &[u32]) -> bool {
        self.keys.clear();
        self.keys.extend(
            a.iter()
                .zip(b)
                .enumerate()
                .map(|(e, (&i, &j))| (key(i, j), e as u32)),
        );
        self.keys.sort_unstable();
        self.tet_edges.clear();
        for tet in &tets.tets {
            let mut codes = [0u32; 6];
            for (code, &(i, j)) in codes.iter_mut().zip(&PAIRS) {
                let Ok(k) = self
                    .keys
                    .binary_search_by_key(&key(tet[i], tet[j]), |kv| kv.0)
                else {
                    self.tet_edges.clear();
                    return false;
                };
                let e = self.keys[k].1;
                *code = if a[e as usize] == tet[i] { e } else { e | FLIP };
            }
            self.tet_edges.push(codes);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::fem::FemMaterial;

    #[test]
    fn the_assembled_product_is_the_element_wise_one() {
        // Two Kuhn cubes side by side (12 elements sharing a face), deformed and rotated.
        let mut rest = Vec::new();
        for i in 0..12 {
            let (x, y, z) = ((i % 3) as f32, ((i / 3) % 2) as f32, (i / 6) as f32);
            rest.push(Vec3::new(x, y, z) * 2.0);
        }
        let node = |x: usize, y: usize, z: usize| (x + 3 * y + 6 * z) as u32;
        let mut tets = Vec::new();
        for cx in 0..2 {
            let corner = |c: usize| node(cx + (c & 1), (c >> 1) & 1, (c >> 2) & 1);
            for t in crate::tissue::KUHN {
                tets.push(t.map(corner));
            }
        }
        let (volumes, dropped) = TetVolumes::new(&tets, &rest, 0.0);
        assert_eq!(dropped, 0);
        let mut fem = FemElements::default();
        let material = FemMaterial {
            youngs_modulus_n_per_mm2: 5e-3,
            poisson_ratio: 0.45,
            corotated: true,
        };
        fem.refill(Some(material), &volumes, &rest);
        // Every element edge, in a scrambled order and orientation.
        let mut edges: Vec<(u32, u32)> = Vec::new();
        for tet in &tets {
            for &(i, j) in &PAIRS {
                let (p, q) = (tet[i].min(tet[j]), tet[i].max(tet[j]));
                if !edges.contains(&(p, q)) && !edges.contains(&(q, p)) {
                    edges.push(if edges.len().is_multiple_of(2) {
                        (p, q)
                    } else {
                        (q, p)
                    });
                }
            }
        }
        edges.reverse();
        let (a, b): (Vec<u32>, Vec<u32>) = edges.iter().copied().unzip();
        let q = nalgebra::UnitQuaternion::from_euler_angles(0.4, -0.7, 1.1);
        let x: Vec<Vec3> = rest
            .iter()
            .enumerate()
            .map(|(i, r)| {
                q * (r + Vec3::new(
                    0.1 * (i as f32).sin(),
                    0.2 * (i as f32 * 0.7).cos(),
                    0.05 * i as f32,
                ))
            })
            .collect();
        let mut lin = FemLinearization::default();
        fem.linearize(&volumes, &x, &mut lin);
        let mut assembled = AssembledStiffness::default();
        assert!(assembled.assemble(&fem, &volumes, &lin, &a, &b, rest.len()));
        let p: Vec<Vec3> = (0..rest.len())
            .map(|i| {
                Vec3::new(
                    (i as f32 * 1.3).sin(),
                    (i as f32 * 0.4).cos(),
                    0.3 - 0.1 * i as f32,
                )
            })
            .collect();
        let mut element_wise = vec![Vec3::zeros(); rest.len()];
        fem.add_stiffness_product(&volumes, &mut lin, &p, 0.5, &mut element_wise);
        let mut blocks = vec![Vec3::zeros(); rest.len()];
        assembled.add_product(&a, &b, &p, 0.5, &mut blocks);
        fem.add_volume_product(&volumes, &mut lin, &p, 0.5, &mut blocks);
        let scale = element_wise.iter().map(|v| v.norm()).fold(0.0f32, f32::max);
        for (e, f) in element_wise.iter().zip(&blocks) {
            assert!((e - f).norm() < 1e-5 * scale, "{e} vs {f}");
        }
        // A missing edge: not assembled, and the product adds nothing.
        assert!(!assembled.assemble(&fem, &volumes, &lin, &a[1..], &b[1..], rest.len()));
        let mut none = vec![Vec3::zeros(); rest.len()];
        assembled.add_product(&a[1..], &b[1..], &p, 0.5, &mut none);
        assert!(none.iter().all(|v| *v == Vec3::zeros()));
        // The map is rebuilt when the edge list changes under it.
        assert!(assembled.assemble(&fem, &volumes, &lin, &b, &a, rest.len()));
        let mut swapped = vec![Vec3::zeros(); rest.len()];
        assembled.add_product(&b, &a, &p, 0.5, &mut swapped);
        fem.add_volume_product(&volumes, &mut lin, &p, 0.5, &mut swapped);
        for (e, f) in element_wise.iter().zip(&swapped) {
            assert!((e - f).norm() < 1e-5 * scale, "{e} vs {f}");
        }
    }
}

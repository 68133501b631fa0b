use super::*;
use crate::tissue::KUHN;
use crate::tissue::volume::{tet_shape_quality, tet_volume_mm3};

/// A sheet of `nx` x `ny` unit squares in z = 0, each split into two triangles, every edge a spring.
fn sheet(nx: u32, ny: u32) -> ModelParts {
    let mut parts = ModelParts::default();
    for y in 0..=ny {
        for x in 0..=nx {
            parts
                .rest_positions_mm
                .push(Vec3::new(x as f32, y as f32, 0.0));
        }
    }
    let row = nx + 1;
    for y in 0..ny {
        for x in 0..nx {
            let v = y * row + x;
            parts.triangles.push([v, v + 1, v + row + 1]);
            parts.triangles.push([v, v + row + 1, v + row]);
        }
    }
    finish(parts)
}

/// A block of `nx` x `ny` x `nz` unit cubes, each split into Kuhn's six tetrahedra.
fn block(nx: u32, ny: u32, nz: u32) -> ModelParts {
    let mut parts = ModelParts::default();
    let id = |x: u32, y: u32, z: u32| (z * (ny + 1) + y) * (nx + 1) + x;
    for z in 0..=nz {
        for y in 0..=ny {
            for x in 0..=nx {
                parts
                    .rest_positions_mm
                    .push(Vec3::new(x as f32, y as f32, z as f32));
            }
        }
    }
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let corner = |bits: usize| {
                    id(
                        x + (bits & 1) as u32,
                        y + ((bits >> 1) & 1) as u32,
                        z + ((bits >> 2) & 1) as u32,
                    )
                };
                for tet in KUHN {
                    parts.tets.push(tet.map(corner));
                }
            }
        }
    }
    // Its surface: the faces one tetrahedron has, turned away from its fourth corner.
    let rest = parts.rest_positions_mm.clone();
    let mut faces: Vec<([u32; 3], [u32; 3])> = Vec::new();
    for tet in &parts.tets {
        for skip in 0..4 {
            let mut face = [0u32; 3];
            let mut k = 0;
            for (i, &v) in tet.iter().enumerate() {
                if i != skip {
                    face[k] = v;
                    k += 1;
                }
            }
            let [a, b, c] = face.map(|v| rest[v as usize]);
            if (b - a).cross(&(c - a)).dot(&(rest[tet[skip] as usize] - a)) > 0.0 {
                face.swap(1, 2);
            }
            let mut key = face;
            key.sort_unstable();
            faces.push((key, face));
        }
    }
    faces.sort_unstable();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        if j - i == 1 {
            parts.triangles.push(faces[i].1);
        }
        i = j;
    }
    finish(parts)
}

/// Masses by measure (1 g per mm^2 or mm^3), springs on every element edge (0.02 N/mm), no anchor.
fn finish(mut parts: ModelParts) -> ModelParts {
    let n = parts.rest_positions_mm.len();
    let rest = parts.rest_positions_mm.clone();
    parts.mass_kg = vec![0.0; n];
    for t in parts.triangles.iter().filter(|_| parts.tets.is_empty()) {
        let [a, b, c] = t.map(|v| rest[v as usize]);
        for &v in t {
            parts.mass_kg[v as usize] += 0.001 * (b - a).cross(&(c - a)).norm() / 6.0;
        }
    }
    for t in &parts.tets {
        for &v in t {
            parts.mass_kg[v as usize] += 0.001 * tet_volume_mm3(&rest, *t).abs() / 4.0;
        }
    }
    parts.fixed = vec![false; n];
    let mut edges: Vec<[u32; 2]> = Vec::new();
    for t in &parts.triangles {
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            edges.push([p.min(q), p.max(q)]);
        }
    }
    for t in &parts.tets {
        for i in 0..4 {
            for j in i + 1..4 {
                edges.push([t[i].min(t[j]), t[i].max(t[j])]);
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    parts.edge_stiffness_n_per_mm = vec![0.02; edges.len()];
    parts.edge_damping_n_s_per_mm = vec![0.0; edges.len()];
    parts.edges = edges;
    parts
}

/// The plan for the plane `normal . x = offset` ([`CutPlan::from_crossings`] over [`plane_crossings`]).
fn plane_plan(model: &MassSpringModel, normal: Vec3, offset: f32) -> CutPlan {
    let mut plan = CutPlan::default();
    plan.from_crossings(
        model,
        &mut plane_crossings(model, normal, offset),
        |_| false,
        |_| false,
    );
    plan
}

/// Every element edge whose ends lie strictly either side of the plane `normal . x = offset`, and where it
/// crosses.
fn plane_crossings(model: &MassSpringModel, normal: Vec3, offset: f32) -> Vec<EdgeSplit> {
    let rest = model.rest_positions_mm();
    let side = |v: u32| normal.dot(&rest[v as usize]) - offset;
    let mut edges: Vec<[u32; 2]> = model
        .springs()
        .a
        .iter()
        .zip(&model.springs().b)
        .map(|(&a, &b)| [a, b])
        .collect();
    edges.sort_unstable();
    edges
        .into_iter()
        .filter(|&[a, b]| side(a) * side(b) < 0.0)
        .map(|[a, b]| EdgeSplit {
            a,
            b,
            t: side(a) / (side(a) - side(b)),
        })
        .collect()
}

/// A tetrahedron's shape quality, unsigned (see [`tet_shape_quality`]).
fn quality(rest: &[Vec3], tet: &[u32; 4]) -> f32 {
    tet_shape_quality(rest, *tet).abs()
}

/// The worst tetrahedron a cut may leave, as a share of the worst before it (see [`quality`]).
const QUALITY_FLOOR: f32 = 0.1;

#[test]
fn a_straight_cut_across_a_sheet_splits_the_crossed_edges_and_keeps_every_id() {
    let model = MassSpringModel::from_parts(sheet(8, 6));
    let before_triangles = model.triangles().to_vec();
    let plan = CutPlan {
        moves: Vec::new(),
        splits: plane_crossings(&model, Vec3::x(), 1.4),
        pinned: Vec::new(),
    };
    assert!(!plan.splits.is_empty());
    let mut parts = ModelParts::default();
    let change = subdivide_into(&model, &plan, &mut parts, rate_ceiling(&model));
    let after = MassSpringModel::from_parts(parts.clone());

    assert_eq!(change.new_vertices.len(), plan.splits.len());
    assert_eq!(change.first_new_vertex, model.node_count() as u32);
    // Old vertices keep their places; new ones lie on the cut.
    for v in 0..model.node_count() {
        assert_eq!(after.rest_positions_mm()[v], model.rest_positions_mm()[v]);
    }
    for v in model.node_count()..after.node_count() {
        assert!((after.rest_positions_mm()[v].x - 1.4).abs() < 1e-5);
    }
    // Triangles untouched keep their corners; every triangle lies on one side, turned as before; area kept.
    for (t, corners) in before_triangles.iter().enumerate() {
        if change
            .changed_elements
            .binary_search_by_key(&(t as u32), |&(e, _)| e)
            .is_err()
        {
            assert_eq!(after.triangles()[t], *corners);
        }
    }
    let rest = after.rest_positions_mm();
    let mut area = 0.0;
    for t in after.triangles() {
        let xs = t.map(|v| rest[v as usize].x - 1.4);
        assert!(
            xs.iter().all(|&x| x <= 1e-5) || xs.iter().all(|&x| x >= -1e-5),
            "{t:?} straddles the cut: {xs:?}"
        );
        let [a, b, c] = t.map(|v| rest[v as usize]);
        let normal = (b - a).cross(&(c - a));
        assert!(normal.z > 0.0, "{t:?} turned over");
        area += 0.5 * normal.norm();
    }
    assert!((area - 48.0).abs() < 1e-3, "area {area}");
    // Mass: the total is kept, unless a light new vertex was made heavier to keep the stable step.
    let total = |m: &MassSpringModel| m.mass_kg().iter().sum::<f32>();
    assert!(
        total(&after) >= total(&model) * 0.9999,
        "{} vs {}",
        total(&after),
        total(&model)
    );
    assert!(
        total(&after) <= total(&model) * 1.05,
        "{} vs {}",
        total(&after),
        total(&model)
    );
    // Springs: the crossed edges are gone, their pieces are springs.
    let springs: Vec<[u32; 2]> = after
        .springs()
        .a
        .iter()
        .zip(&after.springs().b)
        .map(|(&a, &b)| [a.min(b), a.max(b)])
        .collect();
    for (k, s) in plan.splits.iter().enumerate() {
        let p = change.first_new_vertex + k as u32;
        assert!(!springs.contains(&[s.a.min(s.b), s.a.max(s.b)]));
        assert!(springs.contains(&[s.a.min(p), s.a.max(p)]));
        assert!(springs.contains(&[s.b.min(p), s.b.max(p)]));
    }
}

#[test]
fn an_oblique_plane_through_a_block_leaves_every_tetrahedron_on_one_side_and_the_cut_as_faces() {
    let model = MassSpringModel::from_parts(block(3, 2, 2));
    let normal = Vec3::new(1.0, 0.31, 0.17).normalize();
    let offset = normal.dot(&Vec3::new(1.43, 1.0, 1.0));
    let plan = plane_plan(&model, normal, offset);
    let short = plan
        .splits
        .iter()
        .filter(|s| s.t.min(1.0 - s.t) < SNAP_SHARE)
        .count();
    println!(
        "{} moves, {} pinned, {} splits, {short} of them near an end",
        plan.moves.len(),
        plan.pinned.len(),
        plan.splits.len()
    );
    let mut parts = ModelParts::default();
    let change = subdivide_into(&model, &plan, &mut parts, rate_ceiling(&model));
    let after = MassSpringModel::from_parts(parts);
    assert!(change.new_vertices.len() > 10);
    let rest = after.rest_positions_mm();
    // A pinned vertex is on the cut where it lies (at most PIN_SHARE of an edge, sqrt(3) mm at most, off it).
    let side = |v: u32| {
        let d = normal.dot(&rest[v as usize]) - offset;
        if plan.pinned.contains(&v) {
            assert!(
                d.abs() <= PIN_SHARE * 3f32.sqrt(),
                "pinned {v} is {d} mm off the cut"
            );
            0.0
        } else {
            d
        }
    };
    let mut volume = 0.0;
    let mut on_cut_faces = 0;
    let mut worst = f32::INFINITY;
    let before_worst = model
        .tets()
        .tets
        .iter()
        .map(|t| quality(model.rest_positions_mm(), t))
        .fold(f32::INFINITY, f32::min);
    let tets = &after.tets().tets;
    for (e, tet) in tets.iter().enumerate() {
        let s = tet.map(side);
        assert!(
            s.iter().all(|&x| x <= 1e-5) || s.iter().all(|&x| x >= -1e-5),
            "tetrahedron {e} {tet:?} straddles the cut: {s:?}"
        );
        let v = tet_volume_mm3(rest, *tet);
        assert!(v > 0.0, "tetrahedron {e} turned over: {v}");
        worst = worst.min(quality(rest, tet));
        volume += v.abs();
        for skip in 0..4 {
            let face = crate::tissue::seams::facet_without(tet, skip);
            if face.iter().all(|&v| side(v).abs() < 1e-5)
                && crate::tissue::seams::shared_by_two(&after, &face)
            {
                on_cut_faces += 1;
            }
        }
    }
    assert!((volume - 12.0).abs() < 1e-3, "volume {volume}");
    println!("quality: {before_worst:.3} before, {worst:.3} after");
    assert!(
        worst >= QUALITY_FLOOR * before_worst,
        "worst quality {worst} (from {before_worst})"
    );
    // Each face on the cut is counted from both its tetrahedra; the cut crosses the block's 2 x 2 section.
    assert!(on_cut_faces >= 2 * 8, "{on_cut_faces} faces on the cut");
}

#[test]
fn a_point_on_a_split_element_keeps_its_place_to_rounding() {
    for volume in [false, true] {
        let model = MassSpringModel::from_parts(if volume { block(2, 2, 1) } else { sheet(3, 3) });
        let normal = Vec3::new(0.8, 0.55, 0.2).normalize();
        let offset = normal.dot(&Vec3::new(1.37, 1.1, 0.4));
        let plan = CutPlan {
            moves: Vec::new(),
            splits: plane_crossings(&model, normal, offset),
            pinned: Vec::new(),
        };
        let mut parts = ModelParts::default();
        let change = subdivide_into(&model, &plan, &mut parts, rate_ceiling(&model));
        let after = MassSpringModel::from_parts(parts);
        let remap = ElementRemap::new(&change, &after);
        let (before_rest, after_rest) = (model.rest_positions_mm(), after.rest_positions_mm());
        let mut checked = 0;
        let weights4 = [[0.1, 0.2, 0.3, 0.4], [0.7, 0.1, 0.1, 0.1], [0.25; 4]];
        for &(e, _) in &change.changed_elements {
            for w in weights4 {
                let (place, moved) = if volume {
                    let tet = model.tets().tets[e as usize];
                    let place: Vec3 = (0..4).map(|k| before_rest[tet[k] as usize] * w[k]).sum();
                    let (t, w2) = remap.tet(e, w);
                    let now = after.tets().tets[t as usize];
                    (
                        place,
                        (0..4)
                            .map(|k| after_rest[now[k] as usize] * w2[k])
                            .sum::<Vec3>(),
                    )
                } else {
                    let w = [w[0], w[1], w[2] + w[3]];
                    let tri = model.triangles()[e as usize];
                    let place: Vec3 = (0..3).map(|k| before_rest[tri[k] as usize] * w[k]).sum();
                    let (t, w2) = remap.triangle(e, w);
                    let now = after.triangles()[t as usize];
                    (
                        place,
                        (0..3)
                            .map(|k| after_rest[now[k] as usize] * w2[k])
                            .sum::<Vec3>(),
                    )
                };
                // 1e-6 of the element's size (1 mm), as the cutting issue asks.
                assert!((place - moved).norm() < 1e-6, "{place} -> {moved}");
                checked += 1;
            }
        }
        assert!(checked > 10);
    }
}

#[test]
fn a_crossing_near_a_vertex_moves_the_vertex_onto_the_cut_unless_that_would_spoil_an_element() {
    let model = MassSpringModel::from_parts(sheet(3, 3));
    // Vertex 5 is (1, 1): move it 0.2 along the edge to 6 (2, 1).
    let plan = CutPlan {
        moves: vec![VertexMove {
            vertex: 5,
            toward: 6,
            t: 0.2,
        }],
        splits: Vec::new(),
        pinned: Vec::new(),
    };
    let mut parts = ModelParts::default();
    let change = subdivide_into(&model, &plan, &mut parts, rate_ceiling(&model));
    assert_eq!(change.moved.len(), 1);
    assert!(change.new_vertices.is_empty());
    assert!((parts.rest_positions_mm[5] - Vec3::new(1.2, 1.0, 0.0)).norm() < 1e-6);
    // Moved 0.9 of the way, its elements toward 6 would be flattened: it splits the edge instead.
    let plan = CutPlan {
        moves: vec![VertexMove {
            vertex: 5,
            toward: 6,
            t: 0.9,
        }],
        splits: Vec::new(),
        pinned: Vec::new(),
    };
    let change = subdivide_into(&model, &plan, &mut parts, rate_ceiling(&model));
    assert!(change.moved.is_empty());
    assert_eq!(change.new_vertices.len(), 1);
}

//! Applying a cut plan to a model's parts: vertices moved, edges split one after the other, elements re-pointed
//! and appended, and the springs of the split edges and of the new edges.
//!
//! Owns: `apply` and [`move_keeps_quality`]. Must not: share out masses (`shares` does, from the change).

use std::collections::BTreeMap;

use super::*;
use crate::tissue::volume::tet_volume_mm3;

/// A spring's stiffness (N/mm) and damping (N s/mm); `None`: removed.
type SpringEdit = Option<(f32, f32)>;

/// A triangle's area vector at `rest`, mm^2 (twice the area, along its normal).
fn area_vector(rest: &[Vec3], t: [u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|v| rest[v as usize]);
    (b - a).cross(&(c - a))
}

/// Whether moving vertex `v` of `parts` to `to_mm` leaves each of its elements at least [`MIN_MEASURE_SHARE`]
/// of its measure, the same way round. `ring` lists the elements holding `v` (ids into the parts' tetrahedra,
/// or triangles for a sheet).
pub fn move_keeps_quality(parts: &ModelParts, ring: &[u32], v: u32, to_mm: &Vec3) -> bool {
    let rest = &parts.rest_positions_mm;
    let Some(&from) = rest.get(v as usize) else {
        return false;
    };
    let volume = !parts.tets.is_empty();
    ring.iter().all(|&e| {
        let element: Option<&[u32]> = if volume {
            parts.tets.get(e as usize).map(|t| t.as_slice())
        } else {
            parts.triangles.get(e as usize).map(|t| t.as_slice())
        };
        element.is_some_and(|element| keeps_measure(rest, element, v, to_mm))
    }) && from != *to_mm
}

/// Whether `element` (a tetrahedron's four corners or a triangle's three, at `rest`) keeps at least
/// [`MIN_MEASURE_SHARE`] of its measure, the same way round, with vertex `v` moved to `to_mm`.
fn keeps_measure(rest: &[Vec3], element: &[u32], v: u32, to_mm: &Vec3) -> bool {
    let moved = |p: u32| if p == v { *to_mm } else { rest[p as usize] };
    match *element {
        [a, b, c, d] => {
            let before = tet_volume_mm3(rest, [a, b, c, d]);
            let [a, b, c, d] = [a, b, c, d].map(moved);
            let after = (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0;
            before != 0.0 && after / before >= MIN_MEASURE_SHARE
        }
        [a, b, c] => {
            let before = area_vector(rest, [a, b, c]);
            let [a, b, c] = [a, b, c].map(moved);
            let after = (b - a).cross(&(c - a));
            let norm2 = before.norm_squared();
            norm2 > 0.0 && after.dot(&before) >= MIN_MEASURE_SHARE * norm2
        }
        _ => false,
    }
}

/// Whether moving vertex `v` along edge `v w` keeps the object's shape: an inner vertex may move anywhere, one
/// on the surface (a volume's) or the border (a sheet's) only along a surface or border edge, and only where
/// the surface is flat (its triangles at `v` parallel) or the border straight.
fn move_keeps_shape(model: &MassSpringModel, v: u32, w: u32) -> bool {
    let rest = model.rest_positions_mm();
    let triangles = model.triangles();
    let ring = model.node_triangles(v as usize);
    let holding = |x: u32| {
        ring.iter()
            .filter(|&&t| triangles[t as usize].contains(&x))
            .count()
    };
    if !model.tets().tets.is_empty() {
        if ring.is_empty() {
            return true;
        }
        if holding(w) == 0 {
            return false;
        }
        let normal = |t: u32| area_vector(rest, triangles[t as usize]).normalize();
        let first = normal(ring[0]);
        return ring.iter().all(|&t| normal(t).dot(&first) > 1.0 - 1e-6);
    }
    // A sheet: the border edges at `v` are those one triangle holds.
    let mut border: Vec<u32> = Vec::new();
    for &t in ring {
        for &x in &triangles[t as usize] {
            if x != v && holding(x) == 1 && !border.contains(&x) {
                border.push(x);
            }
        }
    }
    if border.is_empty() {
        return true;
    }
    if !border.contains(&w) || border.len() != 2 {
        return false;
    }
    let [a, b] = [border[0], border[1]].map(|x| (rest[x as usize] - rest[v as usize]).normalize());
    a.dot(&b) < -1.0 + 1e-6
}

/// Whether `m` may move its vertex on `model`: it is free, the move keeps the object's shape and each of its
/// elements' quality, and no vertex of its elements is moved by `moves` (so the checks hold as made).
pub(super) fn can_move(model: &MassSpringModel, m: &VertexMove, moves: &[VertexMove]) -> bool {
    let (v, w) = (m.vertex as usize, m.toward as usize);
    let n = model.node_count();
    if v >= n || w >= n || model.is_fixed(v) || !(m.t > 0.0 && m.t < 1.0) {
        return false;
    }
    let volume = !model.tets().tets.is_empty();
    let ring = if volume {
        model.node_tets(v)
    } else {
        model.node_triangles(v)
    };
    let corners = |e: u32| -> &[u32] {
        if volume {
            &model.tets().tets[e as usize]
        } else {
            &model.triangles()[e as usize]
        }
    };
    let neighbour_moves = ring.iter().any(|&e| {
        corners(e)
            .iter()
            .any(|&c| moves.iter().any(|other| other.vertex == c))
    });
    if neighbour_moves || !move_keeps_shape(model, m.vertex, m.toward) {
        return false;
    }
    let rest = model.rest_positions_mm();
    let to = rest[v].lerp(&rest[w], m.t);
    ring.iter()
        .all(|&e| keeps_measure(rest, corners(e), m.vertex, &to))
}

/// Record element `id`'s corners before the change, once.
fn record<T: Copy>(changed: &mut Vec<(u32, T)>, id: u32, before: T) {
    if !changed.iter().any(|&(e, _)| e == id) {
        changed.push((id, before));
    }
}

/// Split every element of `elements` holding edge `a b` (among `ring`, the original elements of `a`, and those
/// appended since `first_new`): the element keeps its index with `b` replaced by `p`, and a copy with `a`
/// replaced by `p` is appended. Returns whether any was split; `each` sees every split element's corners
/// before.
#[allow(clippy::too_many_arguments)]
fn split_in<const K: usize, T: Copy>(
    elements: &mut Vec<[u32; K]>,
    ring: &[u32],
    first_new: u32,
    changed: &mut Vec<(u32, T)>,
    origins: &mut Vec<u32>,
    as_record: impl Fn(&[u32; K]) -> T,
    [a, b, p]: [u32; 3],
    mut each: impl FnMut(&[u32; K]),
) -> bool {
    let appended = elements.len() as u32;
    let mut any = false;
    for id in ring.iter().copied().chain(first_new..appended) {
        let Some(&element) = elements.get(id as usize) else {
            continue;
        };
        let (Some(ia), Some(ib)) = (
            element.iter().position(|&v| v == a),
            element.iter().position(|&v| v == b),
        ) else {
            continue;
        };
        if id < first_new {
            record(changed, id, as_record(&element));
        }
        each(&element);
        let (mut keep, mut new) = (element, element);
        keep[ib] = p;
        new[ia] = p;
        elements[id as usize] = keep;
        elements.push(new);
        origins.push(if id < first_new {
            id
        } else {
            origins[(id - first_new) as usize]
        });
        any = true;
    }
    any
}

/// The spring on edge `e` now: an edit made this change, else the parts' own.
fn spring_of(
    parts: &ModelParts,
    edits: &BTreeMap<[u32; 2], SpringEdit>,
    e: [u32; 2],
) -> SpringEdit {
    if let Some(edit) = edits.get(&e) {
        return *edit;
    }
    let s = parts.edges.binary_search(&e).ok()?;
    Some((
        parts.edge_stiffness_n_per_mm[s],
        parts.edge_damping_n_s_per_mm[s],
    ))
}

fn edge(p: u32, q: u32) -> [u32; 2] {
    [p.min(q), p.max(q)]
}

/// Apply `plan` to `parts` (which hold `model`'s parts): moves first (one that would spoil an element, or of a
/// fixed vertex, becomes a split of its edge), then the splits in order, then the springs merged. Masses of new
/// vertices are left 0 for `shares` to fill.
pub(super) fn apply(
    model: &MassSpringModel,
    plan: &CutPlan,
    parts: &mut ModelParts,
) -> Subdivision {
    let n = parts.rest_positions_mm.len() as u32;
    let volume = !parts.tets.is_empty();
    let element_count = if volume {
        parts.tets.len()
    } else {
        parts.triangles.len()
    } as u32;
    let triangle_count = parts.triangles.len() as u32;
    let mut change = Subdivision {
        first_new_vertex: n,
        first_new_element: element_count,
        first_new_triangle: if volume {
            triangle_count
        } else {
            element_count
        },
        ..Subdivision::default()
    };
    let ring = |v: u32| -> &[u32] {
        if volume {
            model.node_tets(v as usize)
        } else {
            model.node_triangles(v as usize)
        }
    };

    // Moves.
    let mut splits: Vec<EdgeSplit> = Vec::with_capacity(plan.splits.len() + plan.moves.len());
    for m in &plan.moves {
        let (v, w) = (m.vertex, m.toward);
        if v >= n || w >= n || v == w || !(m.t > 0.0 && m.t < 1.0) {
            continue;
        }
        if change.moved.iter().any(|(done, _)| done.vertex == v) {
            continue;
        }
        let from = parts.rest_positions_mm[v as usize];
        let to = from.lerp(&parts.rest_positions_mm[w as usize], m.t);
        if parts.fixed[v as usize]
            || !move_keeps_shape(model, v, w)
            || !move_keeps_quality(parts, ring(v), v, &to)
        {
            splits.push(EdgeSplit { a: v, b: w, t: m.t });
            continue;
        }
        parts.rest_positions_mm[v as usize] = to;
        change.moved.push((*m, from));
        for &e in ring(v) {
            if volume {
                let tet = parts.tets[e as usize];
                record(&mut change.changed_elements, e, corners_of(&tet));
            } else {
                let tri = parts.triangles[e as usize];
                record(&mut change.changed_elements, e, corners_of(&tri));
            }
        }
        if volume {
            for &t in model.node_triangles(v as usize) {
                let tri = parts.triangles[t as usize];
                record(&mut change.changed_triangles, t, tri);
            }
        }
    }
    splits.extend_from_slice(&plan.splits);

    // Splits.
    let moved = |v: u32, change: &Subdivision| change.moved.iter().any(|(m, _)| m.vertex == v);
    let mut edits: BTreeMap<[u32; 2], SpringEdit> = BTreeMap::new();
    for s in &splits {
        let (a, b) = (s.a, s.b);
        if a >= n || b >= n || a == b || !(s.t > 0.0 && s.t < 1.0) {
            continue;
        }
        if moved(a, &change) || moved(b, &change) {
            continue;
        }
        let p = parts.rest_positions_mm.len() as u32;
        // The other corners of every element split: each gets a new edge to `p`.
        let mut others: Vec<u32> = Vec::new();
        let any = if volume {
            let split = split_in(
                &mut parts.tets,
                model.node_tets(a as usize),
                element_count,
                &mut change.changed_elements,
                &mut change.element_origins,
                corners_of,
                [a, b, p],
                |t| others.extend(t.iter().filter(|&&v| v != a && v != b)),
            );
            if split {
                split_in(
                    &mut parts.triangles,
                    model.node_triangles(a as usize),
                    triangle_count,
                    &mut change.changed_triangles,
                    &mut change.triangle_origins,
                    |t| *t,
                    [a, b, p],
                    |_| {},
                );
            }
            split
        } else {
            split_in(
                &mut parts.triangles,
                model.node_triangles(a as usize),
                element_count,
                &mut change.changed_elements,
                &mut change.element_origins,
                corners_of,
                [a, b, p],
                |t| others.extend(t.iter().filter(|&&v| v != a && v != b)),
            )
        };
        if !any {
            continue;
        }
        let rest =
            parts.rest_positions_mm[a as usize].lerp(&parts.rest_positions_mm[b as usize], s.t);
        parts.rest_positions_mm.push(rest);
        parts
            .fixed
            .push(parts.fixed[a as usize] && parts.fixed[b as usize]);
        parts.mass_kg.push(0.0);
        change.new_vertices.push(*s);

        // Springs: the split edge's two pieces keep its spring; each new edge takes the mean of the two it
        // lies between (`a x` and `b x`, edges of the element it crosses).
        let split_spring = spring_of(parts, &edits, edge(a, b));
        edits.insert(edge(a, b), None);
        if let Some(spring) = split_spring {
            edits.insert(edge(a, p), Some(spring));
            edits.insert(edge(p, b), Some(spring));
        }
        others.sort_unstable();
        others.dedup();
        for &x in &others {
            let key = edge(p, x);
            if edits.contains_key(&key) {
                continue;
            }
            let sides = [edge(a, x), edge(b, x)].map(|e| spring_of(parts, &edits, e));
            let (mut k, mut c, mut count) = (0.0, 0.0, 0.0);
            for (ks, cs) in sides.into_iter().flatten() {
                k += ks;
                c += cs;
                count += 1.0;
            }
            if count > 0.0 {
                edits.insert(key, Some((k / count, c / count)));
            }
        }
    }
    change.changed_elements.sort_unstable_by_key(|&(e, _)| e);
    change.changed_triangles.sort_unstable_by_key(|&(t, _)| t);
    if !volume {
        change.first_new_triangle = change.first_new_element;
    }
    merge_springs(parts, &edits);
    change
}

/// Merge the spring edits into the parts' sorted springs.
fn merge_springs(parts: &mut ModelParts, edits: &BTreeMap<[u32; 2], SpringEdit>) {
    if edits.is_empty() {
        return;
    }
    let total = parts.edges.len() + edits.len();
    let (mut edges, mut stiffness, mut damping) = (
        Vec::with_capacity(total),
        Vec::with_capacity(total),
        Vec::with_capacity(total),
    );
    let mut next = edits.iter().peekable();
    for (s, &e) in parts.edges.iter().enumerate() {
        while let Some(&(&key, &edit)) = next.peek() {
            if key >= e {
                break;
            }
            if let Some((k, c)) = edit {
                edges.push(key);
                stiffness.push(k);
                damping.push(c);
            }
            next.next();
        }
        if let Some(&(&key, &edit)) = next.peek()
            && key == e
        {
            if let Some((k, c)) = edit {
                edges.push(key);
                stiffness.push(k);
                damping.push(c);
            }
            next.next();
            continue;
        }
        edges.push(e);
        stiffness.push(parts.edge_stiffness_n_per_mm[s]);
        damping.push(parts.edge_damping_n_s_per_mm[s]);
    }
    for (&key, &edit) in next {
        if let Some((k, c)) = edit {
            edges.push(key);
            stiffness.push(k);
            damping.push(c);
        }
    }
    parts.edges = edges;
    parts.edge_stiffness_n_per_mm = stiffness;
    parts.edge_damping_n_s_per_mm = damping;
}

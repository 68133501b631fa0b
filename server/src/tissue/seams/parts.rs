//! A model with seams opened: the parts to rebuild it from, with each split vertex's mass and each
//! reconsidered spring's stiffness and damping shared out so totals and stable steps are kept.
//!
//! Owns: [`open_model`], [`open_model_into`] and [`open_parts`] (the same on parts not yet built into a model:
//! a cut that follows the blade subdivides and opens in one pass). Must not: rebuild the model or touch its
//! state (the sim does, from the parts and the [`Opening`]).

use super::*;
use crate::tissue::{MassSpringModel, ModelParts};

/// `model` with `seams` opened: the parts of the model to rebuild, and what changed. New vertices start at
/// their parent's rest position, fixed if it was; each parent's mass is shared among it and its copies by the
/// area (sheets) or volume (volumes) of the elements each now has, so the total mass is kept. Springs are the
/// unique edges of the elements again, each with the stiffness and damping of the spring between the parents
/// of its ends. A cut surface is no longer closed, so the global volume term is turned off once anything opens.
/// Allocates: for a cut or tear, not the steady tick.
pub fn open_model(model: &MassSpringModel, seams: &[Facet]) -> (ModelParts, Opening) {
    let mut parts = ModelParts::default();
    let opening = open_model_into(model, seams, &mut parts);
    (parts, opening)
}

/// [`open_model`] into `parts`, reusing its buffers: the sim keeps one per object, so a cut does not fault in
/// fresh pages for a whole model's worth of arrays.
pub fn open_model_into(
    model: &MassSpringModel,
    seams: &[Facet],
    parts: &mut ModelParts,
) -> Opening {
    model.to_parts_into(parts);
    open_parts(parts, seams)
}

/// [`open_model`] on `parts` in place: the parts of a model (springs sorted by edge, as a model's are) with
/// `seams` opened. Opening the parts a model would be rebuilt from, or the model rebuilt from them, gives the
/// same parts.
pub fn open_parts(parts: &mut ModelParts, seams: &[Facet]) -> Opening {
    let n = parts.rest_positions_mm.len() as u32;
    let volume = !parts.tets.is_empty();
    let (old_tets, old_triangles) = if volume {
        (parts.tets.clone(), Vec::new())
    } else {
        (Vec::new(), parts.triangles.clone())
    };
    let mut opening = if volume {
        let before = &old_tets;
        let mut opening = open_seams(&mut parts.tets, n, seams);
        expose_volume_seams(
            before,
            &parts.tets,
            seams,
            &parts.rest_positions_mm,
            &mut parts.triangles,
            &mut opening,
        );
        opening
    } else {
        let mut opening = open_seams(&mut parts.triangles, n, seams);
        opening.changed_triangles = opening.changed_elements.clone();
        opening.first_new_triangle = parts.triangles.len() as u32;
        opening
    };
    if opening.is_empty() {
        opening.changed_elements.clear();
        opening.changed_triangles.clear();
        return opening;
    }
    let parent = |v: u32| -> u32 {
        if v < n {
            v
        } else {
            opening.parents[(v - n) as usize]
        }
    };
    for &p in &opening.parents {
        let rest = parts.rest_positions_mm[p as usize];
        let fixed = parts.fixed[p as usize];
        parts.rest_positions_mm.push(rest);
        parts.fixed.push(fixed);
        parts.mass_kg.push(0.0);
    }

    // Masses: each family (a parent and its copies) shares the parent's mass by element measure (measured only
    // on the elements that hold a member, in element order, so each member's sum is what a pass over every
    // element would give).
    let total = parts.rest_positions_mm.len();
    let mut families: Vec<u32> = opening.parents.clone();
    families.sort_unstable();
    families.dedup();
    let mut member = vec![false; total];
    for &p in &families {
        member[p as usize] = true;
    }
    member[n as usize..].fill(true);
    let mut measure = vec![0.0f32; total];
    let rest = &parts.rest_positions_mm;
    if volume {
        for tet in parts
            .tets
            .iter()
            .filter(|t| t.iter().any(|&i| member[i as usize]))
        {
            let v = crate::tissue::volume::tet_volume_mm3(rest, *tet).abs() / 4.0;
            for &i in tet {
                measure[i as usize] += v;
            }
        }
    } else {
        for tri in parts
            .triangles
            .iter()
            .filter(|t| t.iter().any(|&i| member[i as usize]))
        {
            let [a, b, c] = tri.map(|v| rest[v as usize]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            for &i in tri {
                measure[i as usize] += area;
            }
        }
    }
    let mut family = vec![0.0f32; n as usize];
    for v in (0..total as u32).filter(|&v| member[v as usize]) {
        family[parent(v) as usize] += measure[v as usize];
    }
    // Each family's mass before it is shared out (the parent's own entry is rewritten with its share).
    let family_mass: Vec<f32> = families
        .iter()
        .map(|&p| parts.mass_kg[p as usize])
        .collect();
    for v in 0..total as u32 {
        let p = parent(v);
        let Ok(f) = families.binary_search(&p) else {
            continue;
        };
        if family[p as usize] <= 0.0 {
            continue;
        }
        parts.mass_kg[v as usize] = family_mass[f] * measure[v as usize] / family[p as usize];
    }

    // Springs: an edge no changed element has keeps its spring. The edges of the changed elements, before and
    // after, are reconsidered: each takes the stiffness and damping of the spring between its ends' parents,
    // scaled by the share of that spring's elements it now borders (an edge a seam split between two sides
    // gives each side's copy half, so a split vertex, with half the mass, keeps the stiffness-to-mass ratio and
    // the stable step it had); one no element has any more is gone.
    let (old_tets, old_triangles) = (&old_tets, &old_triangles);
    let (new_tets, new_triangles) = (&parts.tets, &parts.triangles);
    let old_element = |e: usize| -> &[u32] {
        if volume {
            &old_tets[e]
        } else {
            &old_triangles[e]
        }
    };
    let new_element = |e: usize| -> &[u32] {
        if volume {
            &new_tets[e]
        } else {
            &new_triangles[e]
        }
    };
    let new_count = if volume {
        new_tets.len()
    } else {
        new_triangles.len()
    };
    let mut affected: Vec<[u32; 2]> = Vec::new();
    for &e in &opening.changed_elements {
        for element in [old_element(e as usize), new_element(e as usize)] {
            for (i, &p) in element.iter().enumerate() {
                for &q in &element[i + 1..] {
                    affected.push([p.min(q), p.max(q)]);
                }
            }
        }
    }
    affected.sort_unstable();
    affected.dedup();
    let mut ends: Vec<u32> = affected.iter().flatten().copied().collect();
    ends.sort_unstable();
    ends.dedup();
    // The elements around each end of an affected edge, now and before (before: around the parents).
    let mut is_end = vec![false; total];
    for &v in &ends {
        is_end[v as usize] = true;
    }
    let ring = ring_of(new_count, new_element, &is_end);
    let mut is_parent_end = vec![false; n as usize];
    for &v in &ends {
        is_parent_end[parent(v) as usize] = true;
    }
    let old_count = if volume {
        old_tets.len()
    } else {
        old_triangles.len()
    };
    let old_ring = ring_of(old_count, old_element, &is_parent_end);
    let now_count = |edge: [u32; 2]| count_in(&ring, new_element, edge);
    let was_count = |edge: [u32; 2]| count_in(&old_ring, old_element, edge);
    let mut reconsidered: Vec<([u32; 2], f32, f32)> = Vec::with_capacity(affected.len());
    for &edge in &affected {
        let now = now_count(edge);
        if now == 0 {
            continue;
        }
        let (pa, pb) = (parent(edge[0]), parent(edge[1]));
        let key = [pa.min(pb), pa.max(pb)];
        let Ok(s) = parts.edges.binary_search(&key) else {
            continue; // no spring joined the parents (an edge of a new surface triangle only)
        };
        let was = was_count(key);
        let share = if was == 0 {
            1.0
        } else {
            (now as f32 / was as f32).min(1.0)
        };
        reconsidered.push((
            edge,
            parts.edge_stiffness_n_per_mm[s] * share,
            parts.edge_damping_n_s_per_mm[s] * share,
        ));
    }
    // Merge the kept springs (in order) with the reconsidered ones (in order).
    let total = parts.edges.len() + reconsidered.len();
    let (mut edges, mut stiffness, mut damping) = (
        Vec::with_capacity(total),
        Vec::with_capacity(total),
        Vec::with_capacity(total),
    );
    let mut next = reconsidered.iter().peekable();
    for (s, &edge) in parts.edges.iter().enumerate() {
        while let Some(&&(e, k, c)) = next.peek() {
            if e > edge {
                break;
            }
            edges.push(e);
            stiffness.push(k);
            damping.push(c);
            next.next();
        }
        if affected.binary_search(&edge).is_ok() {
            continue;
        }
        edges.push(edge);
        stiffness.push(parts.edge_stiffness_n_per_mm[s]);
        damping.push(parts.edge_damping_n_s_per_mm[s]);
    }
    for &(e, k, c) in next {
        edges.push(e);
        stiffness.push(k);
        damping.push(c);
    }
    parts.edges = edges;
    parts.edge_stiffness_n_per_mm = stiffness;
    parts.edge_damping_n_s_per_mm = damping;
    parts.global_bulk_modulus_n_per_mm2 = 0.0;
    opening
}

/// (vertex, element) for each element of the `count` and each of its vertices marked in `is_end`, sorted.
fn ring_of<'a>(
    count: usize,
    element: impl Fn(usize) -> &'a [u32],
    is_end: &[bool],
) -> Vec<(u32, u32)> {
    let mut ring: Vec<(u32, u32)> = Vec::new();
    for e in 0..count {
        for &v in element(e) {
            if is_end.get(v as usize).copied().unwrap_or(false) {
                ring.push((v, e as u32));
            }
        }
    }
    ring.sort_unstable();
    ring
}

/// How many elements of `ring` around `a` also hold `b`.
fn count_in<'a>(
    ring: &[(u32, u32)],
    element: impl Fn(usize) -> &'a [u32],
    [a, b]: [u32; 2],
) -> usize {
    let from = ring.partition_point(|&(v, _)| v < a);
    ring[from..]
        .iter()
        .take_while(|&&(v, _)| v == a)
        .filter(|&&(_, e)| element(e as usize).contains(&b))
        .count()
}

//! Masses shared out again by measure over the vertices a subdivision touched (their total kept), and a new
//! vertex's mass raised where it would be stiffer for its mass than the model's stiffest node was.
//!
//! Owns: `share_out`. Must not: change the topology (`split` did).

use super::*;
use crate::tissue::stability::DESIGN_STRAIN;
use crate::tissue::volume::tet_volume_mm3;

/// Each corner's share of an element's measure at `rest`: a quarter of a tetrahedron's volume (mm^3), a third
/// of a triangle's area (mm^2).
fn corner_share(rest: &[Vec3], corners: &Corners) -> f64 {
    if corners[3] == NO_VERTEX {
        let [a, b, c] = [0, 1, 2].map(|k| rest[corners[k] as usize]);
        f64::from(0.5 * (b - a).cross(&(c - a)).norm()) / 3.0
    } else {
        f64::from(tet_volume_mm3(rest, *corners).abs()) / 4.0
    }
}

/// The vertices `corners` names.
fn named(corners: &Corners) -> impl Iterator<Item = u32> + '_ {
    corners.iter().copied().filter(|&v| v != NO_VERTEX)
}

/// Share out the masses of the vertices `change` touched by their new measure (each old vertex keeps its mass
/// per measure; a new vertex takes its edge's ends' by where it lies), scaled so their total is kept; then
/// raise any that would be stiffer for its mass than the model's stiffest node (`floor_masses`).
pub(super) fn share_out(
    model: &MassSpringModel,
    change: &Subdivision,
    parts: &mut ModelParts,
    rate_ceiling: f32,
) {
    let volume = !parts.tets.is_empty();
    let n = change.first_new_vertex;
    let element = |parts: &ModelParts, e: u32| -> Corners {
        if volume {
            corners_of(&parts.tets[e as usize])
        } else {
            corners_of(&parts.triangles[e as usize])
        }
    };
    let appended =
        change.first_new_element..change.first_new_element + change.element_origins.len() as u32;

    let mut touched: Vec<u32> = Vec::new();
    for (e, before) in &change.changed_elements {
        touched.extend(named(before));
        touched.extend(named(&element(parts, *e)));
    }
    for e in appended.clone() {
        touched.extend(named(&element(parts, e)));
    }
    touched.sort_unstable();
    touched.dedup();
    let at = |v: u32| touched.binary_search(&v).ok();

    // Measure shares before (the model's rings, at the model's rest) and after (less what the changed elements
    // held before, plus what they and the appended ones hold now).
    let old_rest = model.rest_positions_mm();
    let mut before = vec![0.0f64; touched.len()];
    for (i, &v) in touched.iter().enumerate() {
        if v >= n {
            continue;
        }
        let ring = if volume {
            model.node_tets(v as usize)
        } else {
            model.node_triangles(v as usize)
        };
        for &e in ring {
            let corners = if volume {
                corners_of(&model.tets().tets[e as usize])
            } else {
                corners_of(&model.triangles()[e as usize])
            };
            before[i] += corner_share(old_rest, &corners);
        }
    }
    let mut after = before.clone();
    for (e, corners_before) in &change.changed_elements {
        let was = corner_share(old_rest, corners_before);
        for v in named(corners_before) {
            if let Some(i) = at(v) {
                after[i] -= was;
            }
        }
        let now_corners = element(parts, *e);
        let now = corner_share(&parts.rest_positions_mm, &now_corners);
        for v in named(&now_corners) {
            if let Some(i) = at(v) {
                after[i] += now;
            }
        }
    }
    for e in appended {
        let corners = element(parts, e);
        let now = corner_share(&parts.rest_positions_mm, &corners);
        for v in named(&corners) {
            if let Some(i) = at(v) {
                after[i] += now;
            }
        }
    }

    // Masses: each old vertex keeps its mass per measure, a new one takes its edge's ends' by where it lies;
    // then all are scaled to keep the touched vertices' total.
    let density = |i: usize, v: u32| -> f64 {
        if before[i] > 0.0 {
            f64::from(model.mass_kg()[v as usize]) / before[i]
        } else {
            0.0
        }
    };
    let mut mass = vec![0.0f64; touched.len()];
    let (mut total_before, mut total_after) = (0.0f64, 0.0f64);
    for (i, &v) in touched.iter().enumerate() {
        let rho = if v < n {
            total_before += f64::from(model.mass_kg()[v as usize]);
            density(i, v)
        } else {
            let s = change.new_vertices[(v - n) as usize];
            let (Some(ia), Some(ib)) = (at(s.a), at(s.b)) else {
                continue;
            };
            let t = f64::from(s.t);
            density(ia, s.a) * (1.0 - t) + density(ib, s.b) * t
        };
        mass[i] = rho * after[i].max(0.0);
        total_after += mass[i];
    }
    let scale = if total_after > 0.0 {
        total_before / total_after
    } else {
        1.0
    };
    for (i, &v) in touched.iter().enumerate() {
        parts.mass_kg[v as usize] = (mass[i] * scale) as f32;
    }

    floor_masses(
        parts,
        &touched,
        rate_ceiling,
        model.law().stiffening_at(DESIGN_STRAIN),
    );
}

/// Raise the mass of each vertex of `touched` (free) that would be stiffer for its mass than `omega2_max` (the
/// uncut model's stiffest free node: [`rate_ceiling`], the bound on its stable step as `stability` reads it)
/// to that ratio: a split leaves
/// lighter vertices, and mass scaling keeps the stiffness (what a hand feels) exact where scaling springs would
/// not. No integrator needs a smaller step after the cut. The finite elements' rows are not counted (the
/// corotational model is stepped implicitly).
/// Returns whether any mass was raised.
pub fn floor_masses(
    parts: &mut ModelParts,
    touched: &[u32],
    omega2_max: f32,
    stiffening: f32,
) -> bool {
    if omega2_max.is_nan() || omega2_max <= 0.0 || touched.is_empty() {
        return false;
    }
    let mut raised = false;
    let mut k = vec![0.0f32; touched.len()];
    let at = |v: u32| touched.binary_search(&v).ok();
    for (s, e) in parts.edges.iter().enumerate() {
        for &v in e {
            if let Some(i) = at(v) {
                k[i] += 2.0 * stiffening * parts.edge_stiffness_n_per_mm[s];
            }
        }
    }
    let bulk = parts.tet_bulk_modulus_n_per_mm2;
    if bulk > 0.0 {
        let rest = &parts.rest_positions_mm;
        for &tet in &parts.tets {
            if !tet.iter().any(|&v| at(v).is_some()) {
                continue;
            }
            let volume = tet_volume_mm3(rest, tet).abs();
            if volume <= 0.0 {
                continue;
            }
            let g = crate::tissue::volume::tet_volume_gradients(rest, tet);
            let row: f32 = g.iter().map(|gj| gj.norm()).sum();
            for (corner, &v) in tet.iter().enumerate() {
                if let Some(i) = at(v) {
                    k[i] += bulk / volume * g[corner].norm() * row;
                }
            }
        }
    }
    for (i, &v) in touched.iter().enumerate() {
        let v = v as usize;
        if parts.fixed[v] {
            continue;
        }
        let stiffness = k[i] + parts.anchor_stiffness_n_per_mm;
        let floor = 1000.0 * stiffness / omega2_max;
        if parts.mass_kg[v] < floor {
            parts.mass_kg[v] = floor;
            raised = true;
        }
    }
    raised
}

/// [`floor_masses`] on a built model, in place ([`MassSpringModel::set_node_mass`]): each free vertex of
/// `touched` whose stiffness bound ([`MassSpringModel::node_bounds`]) over its mass passes `omega2_max` gets
/// the mass that brings it to it. Returns whether any was raised.
pub fn floor_model_masses(
    model: &mut MassSpringModel,
    touched: &[u32],
    omega2_max: f32,
    stiffening: f32,
) -> bool {
    if omega2_max.is_nan() || omega2_max <= 0.0 {
        return false;
    }
    let mut raised = false;
    for &v in touched {
        let v = v as usize;
        if v >= model.node_count() || model.is_fixed(v) {
            continue;
        }
        let (k, _) = model.node_bounds(v, stiffening);
        let floor = 1000.0 * k / omega2_max;
        if model.mass_kg()[v] < floor {
            model.set_node_mass(v, floor);
            raised = true;
        }
    }
    raised
}

/// The largest stiffness rate `w^2` (1/s^2) of `model`'s free nodes, as the stability analysis bounds it: the
/// ceiling no node may pass after a cut ([`floor_masses`]).
pub fn rate_ceiling(model: &MassSpringModel) -> f32 {
    model
        .node_rates(model.law().stiffening_at(DESIGN_STRAIN))
        .map(|(w2, _)| w2)
        .fold(0.0f32, f32::max)
}

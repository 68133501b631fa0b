//! A cut that follows the blade (`cut = "follow-blade"`): a straight and a circular cut across the pad and a
//! straight one through the tet block. The cut lies on the blade's path (within 5% of the local edge length),
//! the parts separate, no element turns over or flattens over 1000 ticks after it, the stable step holds, and a
//! grasp on elements the cut splits stays where it was.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use common::mesh_pieces::{assert_closed_surface, pieces};
use common::{quality, worst_kept_quality};
use nalgebra::Vector3;
use sinew_server::interaction::{BladeSweep, CutScratch, GraspSpec, JawInput};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::stability::max_stable_dt_s;
use sinew_server::tissue::{IntegratorName, MassSpringModel, TieSet};
use sinew_server::world::{InstrumentSpec, ToolShapeSpec, World, load_world};

type Vec3 = Vector3<f32>;

/// `worlds/cut.toml` (the pad, object 0, and the tet block, object 1), both cut following the blade.
fn world() -> World {
    let mut world =
        load_world(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/cut.toml"))
            .unwrap();
    for object in &mut world.objects {
        object.material.cut_follows_blade = true;
        object.material.cut_resistance_n = 0.0;
    }
    world
}

/// One tick with no tool: no fault.
fn idle_tick(sim: &mut Sim) {
    let mut out = [ToolOutput::default(); 2];
    let report = sim.step(0.001, &[ToolCommand::default()], &mut out);
    assert_eq!(report.faults, 0, "the guard reset the tissue");
}

/// Sweep a vertical blade (z from `z_mm.0` to `z_mm.1`) through object `object` along `path` (world x, y at
/// `s` from 0 to 1) in `steps` sweeps, a tick after each. Returns the vertices split.
fn sweep_path(
    sim: &mut Sim,
    object: usize,
    z_mm: (f32, f32),
    steps: usize,
    path: impl Fn(f32) -> (f32, f32),
) -> usize {
    let mut scratch = CutScratch::default();
    let blade = |s: f32| {
        let (x, y) = path(s);
        [Vec3::new(x, y, z_mm.0), Vec3::new(x, y, z_mm.1)]
    };
    let mut split = 0;
    for k in 0..steps {
        let sweep = BladeSweep {
            from_mm: blade(k as f32 / steps as f32),
            to_mm: blade((k + 1) as f32 / steps as f32),
        };
        split += sim.cut(object, &sweep, &mut scratch).new_vertices();
        idle_tick(sim);
    }
    split
}

/// The border edges of a sheet (one triangle each) that the cut made: those with a vertex the world did not
/// have, or both of whose ends were not on the border before.
fn cut_border_edges(model: &MassSpringModel, before: &MassSpringModel) -> Vec<[u32; 2]> {
    let border = |triangles: &[[u32; 3]]| {
        let mut edges: Vec<[u32; 2]> = triangles
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        let mut once = Vec::new();
        let mut i = 0;
        while i < edges.len() {
            let mut j = i;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i == 1 {
                once.push(edges[i]);
            }
            i = j;
        }
        once
    };
    let old = border(before.triangles());
    // A piece of a split edge of the old border is border too, but not the cut's: both its ends lie on the
    // old border's line (the pad's rim, at rest).
    let rest = model.rest_positions_mm();
    let on_rim = |v: u32| {
        let p = rest[v as usize];
        (p.x.abs() - 40.0).abs() < 1e-3 || (p.y.abs() - 30.0).abs() < 1e-3
    };
    border(model.triangles())
        .into_iter()
        .filter(|e| old.binary_search(e).is_err() && !(on_rim(e[0]) && on_rim(e[1])))
        .collect()
}

/// Each cut border edge's ends and middle at rest lie within 5% of the edge's length of the path (`off_mm`:
/// a rest point's distance from it); returns the worst share.
fn worst_share_off_path(
    model: &MassSpringModel,
    edges: &[[u32; 2]],
    off_mm: impl Fn(Vec3) -> f32,
) -> f32 {
    let rest = model.rest_positions_mm();
    let mut worst = 0.0f32;
    for &[a, b] in edges {
        let (p, q) = (rest[a as usize], rest[b as usize]);
        let length = (p - q).norm();
        for x in [p, q, (p + q) * 0.5] {
            worst = worst.max(off_mm(x) / length);
        }
    }
    worst
}

/// Set every free node of object `object` moving at up to 50 mm/s in a pseudo-random direction: the cut
/// tissue must ring down, not blow up or turn an element over.
fn kick(sim: &mut Sim, object: usize) {
    let mut seed = 0x2545_f491_u32;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32 * 2.0 - 1.0
    };
    let o = &mut sim.objects[object];
    for (i, v) in o.state.velocities_mm_s.iter_mut().enumerate() {
        let kick = Vec3::new(next(), next(), next()) * 50.0;
        if !o.model.is_fixed(i) {
            *v += kick;
        }
    }
}

/// The stable step of the cut tissue is no shorter than the uncut one's (`before`); then kicked ([`kick`]) and
/// 1000 ticks: no triangle of the sheet turns over (its normal keeps to +z).
fn settles_unturned(sim: &mut Sim, object: usize, before: &MassSpringModel) {
    let stable = |m: &MassSpringModel| max_stable_dt_s(IntegratorName::SymplecticEuler, m).unwrap();
    let (now, then) = (stable(&sim.objects[object].model), stable(before));
    assert!(
        now >= 0.999 * then,
        "the cut needs a step of {now} s, the uncut tissue {then} s"
    );
    kick(sim, object);
    for _ in 0..1000 {
        idle_tick(sim);
    }
    let o = &sim.objects[object];
    let x = &o.state.positions_mm;
    for (t, tri) in o.model.triangles().iter().enumerate() {
        let [a, b, c] = tri.map(|v| x[v as usize]);
        let normal = (b - a).cross(&(c - a));
        assert!(normal.z > 0.0, "triangle {t} {tri:?} turned over: {normal}");
    }
}

#[test]
fn a_straight_cut_across_the_pad_follows_the_blade_and_parts_it() {
    let mut sim = Sim::new(&world()).unwrap();
    let before = sim.objects[0].model.clone();
    // x = 0.37 mm, off the pad's 1 mm grid; 0.1 mm a sweep (100 mm/s) from beyond one border to the other.
    let x0 = 0.37;
    let split = sweep_path(&mut sim, 0, (-4.0, 4.0), 650, |s| (x0, -32.5 + 65.0 * s));
    let model = &sim.objects[0].model;
    let edges = cut_border_edges(model, &before);
    let worst = worst_share_off_path(model, &edges, |p| (p.x - x0).abs());
    println!(
        "straight cut: {split} vertices split, {} vertices now, {} cut border edges, worst {:.3} of an edge off the path",
        model.node_count(),
        edges.len(),
        worst
    );
    assert!(
        edges.len() >= 2 * 60,
        "the cut's border is {} edges",
        edges.len()
    );
    assert!(
        worst <= 0.05,
        "the cut lies {worst} of an edge off the blade's path"
    );
    assert_eq!(pieces(model.triangles(), model.node_count()), 2);
    settles_unturned(&mut sim, 0, &before);
}

#[test]
fn a_cut_beside_tied_vertices_splits_their_edges_and_leaves_them_where_they_were() {
    // The pad's free vertices on the line x = 0 tied to the block's first vertex (a tie holds a node by its id
    // and its rest offset). A cut along x = 0.2 crosses their edges a fifth of the way along: untied, they
    // would move onto it; tied, their edges split and they stay.
    let mut world = world();
    let pad = &world.objects[0].mesh.positions_mm;
    let anchor = Vec3::from(world.objects[1].mesh.positions_mm[0]);
    let pairs: Vec<(u32, u32, Vec3)> = pad
        .iter()
        .enumerate()
        .filter(|(_, p)| p[0].abs() < 1e-4 && p[1].abs() < 29.5)
        .map(|(i, p)| (i as u32, 0, anchor - Vec3::from(*p)))
        .collect();
    assert_eq!(pairs.len(), 59);
    world.ties.push(TieSet {
        object_a: 0,
        object_b: 1,
        pairs: pairs.clone(),
        stiffness_n_per_mm: 0.01,
        damping_n_s_per_mm: 0.0,
    });
    let mut sim = Sim::new(&world).unwrap();
    let before = sim.objects[0].model.clone();
    let x0 = 0.2;
    let split = sweep_path(&mut sim, 0, (-4.0, 4.0), 650, |s| (x0, -32.5 + 65.0 * s));
    let model = &sim.objects[0].model;
    let moved = pairs
        .iter()
        .filter(|&&(v, _, _)| {
            model.rest_positions_mm()[v as usize] != before.rest_positions_mm()[v as usize]
        })
        .count();
    let edges = cut_border_edges(model, &before);
    let worst = worst_share_off_path(model, &edges, |p| (p.x - x0).abs());
    println!(
        "cut beside {} tied vertices: {split} vertices split, {moved} tied vertices moved, worst {worst:.3} of an edge off the path",
        pairs.len()
    );
    assert_eq!(moved, 0, "a cut moved a tied vertex");
    assert!(
        worst <= 0.05,
        "the cut lies {worst} of an edge off the path"
    );
    assert_eq!(pieces(model.triangles(), model.node_count()), 2);
    // Untied, the same cut moves them (the test would not tell otherwise).
    let mut untied = Sim::new(&self::world()).unwrap();
    sweep_path(&mut untied, 0, (-4.0, 4.0), 650, |s| (x0, -32.5 + 65.0 * s));
    let rest = untied.objects[0].model.rest_positions_mm();
    let moved_untied = pairs
        .iter()
        .filter(|&&(v, _, _)| rest[v as usize] != before.rest_positions_mm()[v as usize])
        .count();
    assert!(
        moved_untied > 30,
        "untied, only {moved_untied} moved onto the cut"
    );
}

#[test]
fn a_curved_cut_across_the_pad_follows_the_blade_and_parts_it() {
    let mut sim = Sim::new(&world()).unwrap();
    let before = sim.objects[0].model.clone();
    // An arc of 50 mm radius about (0, -45): it enters at the left rim (x = -40, y = -15), rises to y = 5 and
    // leaves at the right rim; begun and ended beyond the rim, 0.1 mm a sweep.
    let (r, c) = (50.0f32, (0.0f32, -45.0f32));
    let (a0, a1) = (2.55f32, 0.59f32);
    let steps = ((a0 - a1) * r / 0.1) as usize;
    let split = sweep_path(&mut sim, 0, (-4.0, 4.0), steps, |s| {
        let a = a0 + (a1 - a0) * s;
        (c.0 + r * a.cos(), c.1 + r * a.sin())
    });
    let model = &sim.objects[0].model;
    let edges = cut_border_edges(model, &before);
    let worst = worst_share_off_path(model, &edges, |p| ((p.x - c.0).hypot(p.y - c.1) - r).abs());
    println!(
        "arc cut: {split} vertices split, {} cut border edges, worst {:.3} of an edge off the path",
        edges.len(),
        worst
    );
    assert!(
        edges.len() >= 2 * 85,
        "the cut's border is {} edges",
        edges.len()
    );
    assert!(
        worst <= 0.05,
        "the cut lies {worst} of an edge off the blade's path"
    );
    assert_eq!(pieces(model.triangles(), model.node_count()), 2);
    settles_unturned(&mut sim, 0, &before);
}

const TURNS: f32 = 1.2;

#[test]
fn a_circular_cut_in_the_pad_follows_the_blade_and_frees_a_disc() {
    let mut sim = Sim::new(&world()).unwrap();
    let before = sim.objects[0].model.clone();
    // A circle of 10.3 mm about (0.2, 0.1), a little over once round, 0.1 mm a sweep.
    let (r, c) = (10.3f32, (0.2f32, 0.1f32));
    let turn = TURNS * std::f32::consts::TAU;
    let steps = (turn * r / 0.1) as usize;
    let split = sweep_path(&mut sim, 0, (-4.0, 4.0), steps, |s| {
        (c.0 + r * (turn * s).cos(), c.1 + r * (turn * s).sin())
    });
    let model = &sim.objects[0].model;
    {
        // Debug: inner edges with both ends on the circle.
        let rest = model.rest_positions_mm();
        let off = |v: u32| ((rest[v as usize].x - c.0).hypot(rest[v as usize].y - c.1) - r).abs();
        let mut all: Vec<[u32; 2]> = model
            .triangles()
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        all.sort_unstable();
        for w in all.windows(2) {
            if w[0] == w[1] && off(w[0][0]) < 0.05 && off(w[0][1]) < 0.05 {
                let (p, q) = (rest[w[0][0] as usize], rest[w[0][1] as usize]);
                println!(
                    "shut {:?} {:?} -> {:?} angle {:.3}",
                    w[0],
                    p,
                    q,
                    (p.y - c.1).atan2(p.x - c.0)
                );
            }
        }
    }
    let edges = cut_border_edges(model, &before);
    let worst = worst_share_off_path(model, &edges, |p| ((p.x - c.0).hypot(p.y - c.1) - r).abs());
    println!(
        "circular cut: {split} vertices split, {} cut border edges, worst {:.3} of an edge off the path",
        edges.len(),
        worst
    );
    assert!(
        worst <= 0.05,
        "the cut lies {worst} of an edge off the blade's path"
    );
    assert_eq!(pieces(model.triangles(), model.node_count()), 2);
    settles_unturned(&mut sim, 0, &before);
}

/// The worst shape quality a cut may leave in the block, as a share of the uncut block's worst.
const BLOCK_QUALITY_FLOOR: f32 = 0.05;

/// Cut the tet block (object 1: x 50 to 90, y -15 to 15, z -10 to 0, its base and far end fixed) with a blade
/// reaching from 2 mm below its base to 2 mm above its top along `path`; then the checks every block cut must
/// pass: the cut's faces lie on the path within 5% of their edges (`off_mm`: a rest point's distance from the
/// path's surface), the block is in two closed pieces, the worst element keeps [`BLOCK_QUALITY_FLOOR`] of the
/// worst quality before, the stable step holds, and kicked ([`kick`]) no tetrahedron turns over in 1000 ticks
/// and all are back within half their rest quality.
fn cut_block(steps: usize, path: impl Fn(f32) -> (f32, f32), off_mm: impl Fn(Vec3) -> f32) {
    let mut sim = Sim::new(&world()).unwrap();
    let before = sim.objects[1].model.clone();
    let split = sweep_path(&mut sim, 1, (-12.0, 2.0), steps, path);
    let model = &sim.objects[1].model;
    let rest = model.rest_positions_mm();
    // The cut's faces: surface triangles the block did not have that do not lie on one of its six sides.
    let mut old: Vec<[u32; 3]> = before.triangles().to_vec();
    old.sort_unstable();
    let on_side = |t: &[u32; 3]| {
        let p = t.map(|v| rest[v as usize]);
        let flat = |k: usize, at: f32| p.iter().all(|q| (q[k] - at).abs() < 1e-3);
        flat(0, 50.0)
            || flat(0, 90.0)
            || flat(1, -15.0)
            || flat(1, 15.0)
            || flat(2, -10.0)
            || flat(2, 0.0)
    };
    let faces: Vec<[u32; 3]> = model
        .triangles()
        .iter()
        .filter(|t| old.binary_search(t).is_err() && !on_side(t))
        .copied()
        .collect();
    let mut worst_off = 0.0f32;
    for t in &faces {
        let p = t.map(|v| rest[v as usize]);
        let edge = ((p[0] - p[1]).norm() + (p[1] - p[2]).norm() + (p[2] - p[0]).norm()) / 3.0;
        for x in [p[0], p[1], p[2], (p[0] + p[1] + p[2]) / 3.0] {
            worst_off = worst_off.max(off_mm(x) / edge);
        }
    }
    let tets = &model.tets().tets;
    let worst_quality = |m: &MassSpringModel| {
        m.tets()
            .tets
            .iter()
            .map(|t| quality(m.rest_positions_mm(), t))
            .fold(f32::INFINITY, f32::min)
    };
    let (q_before, q_after) = (worst_quality(&before), worst_quality(model));
    println!(
        "block cut: {split} vertices split, {} tetrahedra (from {}), {} cut faces, worst {:.3} of an edge off \
         the path, worst quality {q_after:.3} (uncut {q_before:.3})",
        tets.len(),
        before.tets().tets.len(),
        faces.len(),
        worst_off
    );
    assert!(faces.len() >= 2 * 30, "the cut shows {} faces", faces.len());
    assert!(
        worst_off <= 0.05,
        "the cut lies {worst_off} of an edge off the blade's path"
    );
    assert_eq!(pieces(tets, model.node_count()), 2);
    assert_closed_surface(model.triangles());
    assert!(
        q_after >= BLOCK_QUALITY_FLOOR * q_before,
        "worst quality {q_after} from {q_before}"
    );
    let stable = |m: &MassSpringModel| max_stable_dt_s(IntegratorName::SymplecticEuler, m).unwrap();
    let (now, then) = (stable(model), stable(&before));
    assert!(
        now >= 0.999 * then,
        "the cut needs a step of {now} s, the uncut block {then} s"
    );
    kick(&mut sim, 1);
    let mut worst_seen = f32::INFINITY;
    for k in 0..1000 {
        idle_tick(&mut sim);
        if k % 10 == 0 {
            let o = &sim.objects[1];
            for t in &o.model.tets().tets {
                worst_seen = worst_seen.min(
                    quality(&o.state.positions_mm, t) / quality(o.model.rest_positions_mm(), t),
                );
            }
        }
    }
    let o = &sim.objects[1];
    let worst_now = worst_kept_quality(o);
    println!(
        "kicked, then 1000 ticks: the worst tetrahedron keeps {worst_now:.3} of its rest quality; at worst \
         {worst_seen:.3} on the way"
    );
    assert!(
        worst_now > 0.5,
        "a tetrahedron flattened or turned over: {worst_now}"
    );
    assert!(worst_seen > 0.0, "a tetrahedron turned over: {worst_seen}");
}

#[test]
fn a_straight_cut_through_the_tet_block_follows_the_blade_and_parts_it_into_two_closed_pieces() {
    let x0 = 63.37;
    cut_block(340, |s| (x0, -17.0 + 34.0 * s), |p| (p.x - x0).abs());
}

#[test]
fn a_curved_cut_through_the_tet_block_follows_the_blade_and_parts_it_into_two_closed_pieces() {
    // An arc of 25 mm radius about (45, 0.3), from beyond one long side to beyond the other.
    let (r, c) = (25.0f32, (45.0f32, 0.3f32));
    let (a0, a1) = (-0.75f32, 0.75f32);
    let steps = ((a1 - a0) * r / 0.1) as usize;
    cut_block(
        steps,
        |s| {
            let a = a0 + (a1 - a0) * s;
            (c.0 + r * a.cos(), c.1 + r * a.sin())
        },
        |p| ((p.x - c.0).hypot(p.y - c.1) - r).abs(),
    );
}

/// Where each of tool 0's grasp attachments holds the tissue now, world frame, mm.
fn held_points(sim: &Sim) -> Vec<Vec3> {
    let o = &sim.objects[0];
    sim.tools[0]
        .grasp()
        .unwrap()
        .attachments()
        .iter()
        .map(|a| {
            let corners = o.model.triangles()[a.triangle as usize];
            (0..3)
                .map(|k| o.state.positions_mm[corners[k] as usize] * a.barycentric[k])
                .sum()
        })
        .collect()
}

#[test]
fn a_grasp_on_triangles_a_cut_splits_holds_the_same_points_and_holds_on() {
    // The pad (1 mm grid) cut following the blade, its left probe a grasper that holds up to 20 N a point.
    let mut world =
        load_world(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml"))
            .unwrap();
    world.objects[0].material.cut_follows_blade = true;
    let sphere = ToolShapeSpec::Sphere { radius_mm: 4.0 };
    for tool in world.tools.iter_mut().filter(|t| t.shape == sphere) {
        tool.instrument = InstrumentSpec::Grasper(GraspSpec {
            slip_force_n: 20.0,
            ..GraspSpec::DEFAULT
        });
    }
    let mut sim = Sim::new(&world).unwrap();
    // Tool 0 (device origin at world x = -18): its sphere's bottom pressed from 6 mm above to 2 mm into the
    // pad, then the jaws close.
    let at = |depth_mm: f32, closed: bool| ToolCommand {
        active: true,
        position_device_mm: [0.0, 0.0, 4.0 - depth_mm],
        jaws: JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    };
    let mut out = [ToolOutput::default(); 2];
    for k in 0..400 {
        let depth = -6.0 + 8.0 * (k + 1) as f32 / 400.0;
        sim.step(0.001, &[at(depth, false)], &mut out);
    }
    for _ in 0..100 {
        sim.step(0.001, &[at(2.0, true)], &mut out);
    }
    let held = sim.tools[0].grasp().unwrap().attachments().to_vec();
    assert!(held.len() > 4, "the grasp holds {} points", held.len());
    // A blade across the grasped patch at x = -18.37 (off the grid), 0.1 mm a sweep; after each sweep the
    // points held are where they were before it.
    let x0 = -18.37;
    let mut scratch = CutScratch::default();
    let (mut worst_mm, mut moved_triangles, mut split) = (0.0f32, 0, 0);
    let blade = |y: f32| [Vec3::new(x0, y, -4.0), Vec3::new(x0, y, 4.0)];
    for k in 0..100 {
        let y = -5.0 + 0.1 * k as f32;
        let before = held_points(&sim);
        let triangles: Vec<u32> = sim.tools[0]
            .grasp()
            .unwrap()
            .attachments()
            .iter()
            .map(|a| a.triangle)
            .collect();
        let sweep = BladeSweep {
            from_mm: blade(y),
            to_mm: blade(y + 0.1),
        };
        split += sim.cut(0, &sweep, &mut scratch).new_vertices();
        let after = held_points(&sim);
        assert_eq!(before.len(), after.len(), "a cut let go of a point");
        for (p, q) in before.iter().zip(&after) {
            worst_mm = worst_mm.max((p - q).norm());
        }
        moved_triangles += sim.tools[0]
            .grasp()
            .unwrap()
            .attachments()
            .iter()
            .zip(&triangles)
            .filter(|(a, t)| a.triangle != **t)
            .count();
        let report = sim.step(0.001, &[at(2.0, true)], &mut out);
        assert_eq!(report.faults, 0);
        assert_eq!(report.attachments_released, 0, "the cut let go");
    }
    println!(
        "{} points held; the cut split {split} vertices, moved points to {moved_triangles} new triangles; the \
         held points moved at most {worst_mm:.2e} mm across a cut",
        held.len()
    );
    assert!(moved_triangles > 0, "the cut split no held triangle");
    // 1e-5 of the 1 mm elements: f32 resolves 1.9e-6 mm at 18 mm from the origin.
    assert!(
        worst_mm <= 1e-5,
        "a held point moved {worst_mm} mm across a cut"
    );
}

#[test]
fn a_cut_through_the_corotational_fem_block_follows_the_blade_and_parts_it() {
    // worlds/fem_block.toml: the same tet block as elastic elements (implicit Euler), its base and one end fixed.
    let mut world = load_world(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/fem_block.toml"),
    )
    .unwrap();
    world.objects[0].material.cut_follows_blade = true;
    let mut sim = Sim::new(&world).unwrap();
    let before = sim.objects[0].model.tets().tets.len();
    // Across the block (x -20 to 20, y -15 to 15, z -10 to 0) at x = -5.2, through its depth.
    let x0 = -5.2;
    let split = sweep_path(&mut sim, 0, (-12.0, 2.0), 340, |s| (x0, -17.0 + 34.0 * s));
    let model = &sim.objects[0].model;
    println!(
        "fem block cut: {split} vertices split, {} tetrahedra (from {before})",
        model.tets().tets.len()
    );
    assert!(model.tets().tets.len() > before);
    assert_eq!(pieces(&model.tets().tets, model.node_count()), 2);
    assert_closed_surface(model.triangles());
    kick(&mut sim, 0);
    for _ in 0..1000 {
        idle_tick(&mut sim);
    }
    let o = &sim.objects[0];
    assert!(o.state.is_finite());
    let worst = worst_kept_quality(o);
    println!("kicked, then 1000 ticks: the worst tetrahedron keeps {worst:.3} of its rest quality");
    assert!(
        worst > 0.5,
        "a tetrahedron flattened or turned over: {worst}"
    );
}

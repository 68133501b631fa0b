//! Cutting and tearing on virtual time, on the shipped pad (a sheet) and tet block (a volume): a blade drawn
//! across parts the tissue along its path and every id made before stays valid; the cut opens under tension
//! and pulls back less than whole tissue; a grasp made before a cut holds through it; every integrator steps
//! the cut tissue; a volume cut through shows its cut faces as a closed surface; an overstretched sheet tears;
//! scissors cut only as they close, between their blades, and a line of snips parts a sheet or opens a block.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use common::mesh_pieces::{assert_closed_surface, pieces};
use common::scene_edits::with_integrator;
use common::world_toml::{SIM_DEFAULTS, SheetWorldToml, fixed_plane, sphere_tool};
use nalgebra::Vector3;
use sinew_server::interaction::{BladeSweep, CutScratch, JawInput};
use sinew_server::sim::{Sim, StepReport, ToolCommand, ToolOutput};
use sinew_server::tissue::seams::Opening;
use sinew_server::world::{
    GraspSpec, InstrumentSpec, IntegratorName, ScissorsSpec, ToolShapeSpec, World, load_world,
};

type Vec3 = Vector3<f32>;

/// A shipped world, loaded as it is.
fn shipped(name: &str) -> World {
    load_world(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../worlds")
            .join(name),
    )
    .unwrap()
}

/// The pad with `method`, at the largest step of 1, 0.25 and 0.1 ms the loader accepts for it, and both its
/// probes `instrument` (`None`: probes).
fn pad_with(method: IntegratorName, instrument: Option<InstrumentSpec>) -> Sim {
    pad_edited(method, instrument, |_| {})
}

/// [`pad_with`], its world edited first by `edit` (before the step is chosen: the edit may move the bound).
fn pad_edited(
    method: IntegratorName,
    instrument: Option<InstrumentSpec>,
    edit: impl Fn(&mut World),
) -> Sim {
    let mut world = shipped("pad.toml");
    edit(&mut world);
    let mut world = with_integrator(world, 0, method, &[0.001, 0.00025, 0.0001]);
    if let Some(instrument) = instrument {
        let sphere = ToolShapeSpec::Sphere { radius_mm: 4.0 };
        for tool in world.tools.iter_mut().filter(|t| t.shape == sphere) {
            tool.instrument = instrument;
        }
    }
    Sim::new(&world).unwrap()
}

/// The pad's probes as graspers that hold up to 20 N a point (`instrument = { kind = "grasper",
/// slip_force_n = 20.0 }`).
fn strong_grasper() -> Option<InstrumentSpec> {
    Some(InstrumentSpec::Grasper(GraspSpec {
        slip_force_n: 20.0,
        ..GraspSpec::DEFAULT
    }))
}

/// One tick with tool 0 at `command` (tool 1 absent); the report, with no fault and a finite force.
fn tick(sim: &mut Sim, command: ToolCommand) -> (ToolOutput, StepReport) {
    let mut out = [ToolOutput::default(); 2];
    let report = sim.step(0.001, &[command], &mut out);
    assert_eq!(report.faults, 0, "the guard reset the tissue");
    assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
    (out[0], report)
}

/// Tool 0 (device origin at world x = -18 on the pad) with its 4 mm sphere's bottom `depth_mm` below the rest
/// surface, `dx_mm` along x, jaws closed or open.
fn tool_at(dx_mm: f32, depth_mm: f32, closed: bool) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [dx_mm, 0.0, 4.0 - depth_mm],
        jaws: JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    }
}

/// Draw a vertical blade (`z` from -`half_height_mm` to +`half_height_mm`) at world `x_mm` along y from
/// `y0_mm` to `y1_mm`, 1 mm a tick, stepping the sim with tool 0 at `command` each tick. The openings, merged.
fn draw_blade(
    sim: &mut Sim,
    object: usize,
    x_mm: f32,
    (y0_mm, y1_mm): (f32, f32),
    half_height_mm: f32,
    command: ToolCommand,
) -> Vec<Opening> {
    let mut scratch = CutScratch::default();
    let blade = |y: f32| {
        [
            Vec3::new(x_mm, y, -half_height_mm),
            Vec3::new(x_mm, y, half_height_mm),
        ]
    };
    let mut openings = Vec::new();
    let mut y = y0_mm;
    while y < y1_mm {
        let next = (y + 1.0).min(y1_mm);
        let sweep = BladeSweep {
            from_mm: blade(y),
            to_mm: blade(next),
        };
        let opening = sim.cut(object, &sweep, &mut scratch);
        if !opening.is_empty() {
            openings.push(opening);
        }
        tick(sim, command);
        y = next;
    }
    openings
}

fn total_mass(sim: &Sim, object: usize) -> f64 {
    sim.objects[object]
        .model
        .mass_kg()
        .iter()
        .map(|&m| f64::from(m))
        .sum()
}

/// Largest distance between a split vertex and its parent: how far the cut has opened.
fn opened_mm(sim: &Sim, openings: &[Opening]) -> f32 {
    let x = &sim.objects[0].state.positions_mm;
    openings
        .iter()
        .flat_map(|o| {
            o.parents
                .iter()
                .enumerate()
                .map(move |(k, &p)| (o.first_new_vertex as usize + k, p as usize))
        })
        .map(|(c, p)| (x[c] - x[p]).norm())
        .fold(0.0, f32::max)
}

#[test]
fn a_blade_drawn_across_the_pad_parts_it_in_two_and_every_id_made_before_stays_valid() {
    let mut sim = pad_with(IntegratorName::SymplecticEuler, None);
    let before = sim.objects[0].model.clone();
    let mass_before = total_mass(&sim, 0);
    assert_eq!(
        pieces(before.triangles(), before.node_count()),
        1,
        "the pad starts whole"
    );
    let openings = draw_blade(&mut sim, 0, 0.3, (-35.0, 35.0), 3.0, ToolCommand::default());
    let after = &sim.objects[0].model;
    let added: usize = openings.iter().map(Opening::new_vertices).sum();
    println!(
        "{} openings, {added} vertices added to {}, {} triangles",
        openings.len(),
        before.node_count(),
        after.triangles().len()
    );
    assert!(added > 0, "the blade cut nothing");
    assert_eq!(after.node_count(), before.node_count() + added);
    assert_eq!(
        pieces(after.triangles(), after.node_count()),
        2,
        "not parted"
    );
    // No element or vertex was renumbered: triangles keep their slots, old vertices their rest positions, and
    // each triangle's corners are its old ones or copies of them.
    assert_eq!(after.triangles().len(), before.triangles().len());
    assert_eq!(
        &after.rest_positions_mm()[..before.node_count()],
        before.rest_positions_mm()
    );
    let mut parent: Vec<u32> = (0..before.node_count() as u32).collect();
    for o in &openings {
        assert_eq!(
            o.first_new_vertex as usize,
            parent.len(),
            "ids are appended"
        );
        let roots: Vec<u32> = o.parents.iter().map(|&p| parent[p as usize]).collect();
        parent.extend(roots);
    }
    for (old, new) in before.triangles().iter().zip(after.triangles()) {
        assert_eq!(*old, new.map(|v| parent[v as usize]));
    }
    // Only vertices near the blade's path split, and the mass is kept.
    for &p in &parent[before.node_count()..] {
        let x = before.rest_positions_mm()[p as usize].x;
        assert!((x - 0.3).abs() < 3.0, "vertex at x = {x} split");
    }
    let mass_after = total_mass(&sim, 0);
    assert!(
        ((mass_after - mass_before) / mass_before).abs() < 1e-5,
        "{mass_before} kg -> {mass_after} kg"
    );
    // The parted pad still steps and rests where it was.
    for _ in 0..300 {
        tick(&mut sim, ToolCommand::default());
    }
    assert!(opened_mm(&sim, &openings) < 0.01, "a cut at rest opened");
}

#[test]
fn a_grasp_made_before_a_cut_holds_through_it_and_the_cut_opens_and_pulls_back_less() {
    let pull = |cut: bool| -> (f32, f32, usize, StepReport) {
        // No anchors to the tissue underneath: the pull is held by the sheet alone, as a membrane.
        let mut sim = pad_edited(IntegratorName::SymplecticEuler, strong_grasper(), |w| {
            let material = &mut w.objects[0].material;
            assert_eq!(material.anchor_stiffness_n_per_mm, 0.008);
            material.anchor_stiffness_n_per_mm = 0.0;
        });
        for k in 0..400 {
            let depth = -6.0 + 8.0 * (k + 1) as f32 / 400.0;
            tick(&mut sim, tool_at(0.0, depth, false));
        }
        let (_, took) = tick(&mut sim, tool_at(0.0, 2.0, true));
        for _ in 0..100 {
            tick(&mut sim, tool_at(0.0, 2.0, true));
        }
        let held = sim.tools[0].grasp().unwrap().attachments().len();
        assert!(took.grasps_taken == 1 && held > 0, "no grasp: {took:?}");
        // Cut across the pad 7 mm right of the grasper's centre (world x = -11).
        let openings = if cut {
            draw_blade(
                &mut sim,
                0,
                -11.0,
                (-35.0, 35.0),
                4.0,
                tool_at(0.0, 2.0, true),
            )
        } else {
            Vec::new()
        };
        // Pull 3 mm away from the cut (toward -x) over 0.5 s, and hold (below the 3.3 N clamp).
        let mut events = StepReport::default();
        let mut last = ToolOutput::default();
        for k in 0..800 {
            let dx = -3.0 * ((k + 1) as f32 / 500.0).min(1.0);
            let (out, report) = tick(&mut sim, tool_at(dx, 2.0, true));
            events.attachments_released += report.attachments_released;
            events.attachments_slipped += report.attachments_slipped;
            last = out;
        }
        let now = sim.tools[0].grasp().unwrap().attachments().len();
        assert_eq!(now, held, "attachments lost (cut: {cut})");
        let force = Vector3::from(last.force_world_n);
        (force.norm(), opened_mm(&sim, &openings), held, events)
    };
    let (whole_n, _, _, whole_events) = pull(false);
    let (cut_n, opened, held, cut_events) = pull(true);
    println!(
        "pull 3 mm: whole {whole_n:.3} N, cut {cut_n:.3} N; the cut opened {opened:.2} mm; {held} points held"
    );
    assert_eq!(whole_events.attachments_released, 0);
    assert_eq!(cut_events.attachments_released, 0, "the cut let go");
    assert_eq!(cut_events.attachments_slipped, 0, "the cut let go");
    assert!(
        opened > 0.5,
        "the cut did not open under tension: {opened} mm"
    );
    assert!(
        cut_n < 0.95 * whole_n,
        "cut tissue pulled back as hard as whole: {cut_n} N vs {whole_n} N"
    );
}

#[test]
fn every_integrator_steps_a_cut_pad_pressed_beside_the_cut() {
    for method in IntegratorName::ALL {
        let mut sim = pad_with(method, None);
        let openings = draw_blade(
            &mut sim,
            0,
            -12.3,
            (-35.0, 35.0),
            3.0,
            ToolCommand::default(),
        );
        assert!(!openings.is_empty(), "{}: nothing cut", method.as_str());
        // Press 3 mm just left of the cut, then let go.
        let mut deepest = 0.0f32;
        for k in 0..600 {
            let depth = if k < 300 {
                -4.0 + 7.0 * (k + 1) as f32 / 300.0
            } else {
                3.0
            };
            tick(&mut sim, tool_at(3.0, depth, false));
            let z = sim.objects[0]
                .state
                .positions_mm
                .iter()
                .map(|p| -p.z)
                .fold(0.0, f32::max);
            deepest = deepest.max(z);
        }
        for _ in 0..300 {
            tick(&mut sim, ToolCommand::default());
        }
        assert!(sim.objects[0].state.is_finite(), "{}", method.as_str());
        println!("{}: deepest dent {deepest:.2} mm", method.as_str());
        assert!(
            deepest > 1.5,
            "{}: the cut pad did not dent",
            method.as_str()
        );
    }
}

#[test]
fn a_blade_through_the_tet_block_parts_it_into_two_closed_surfaces() {
    let mut sim = Sim::new(&shipped("tet_block.toml")).unwrap();
    let rest = sim.objects[0].model.rest_positions_mm().to_vec();
    let (lo, hi) = rest.iter().fold(
        (Vec3::repeat(f32::MAX), Vec3::repeat(f32::MIN)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let surface_before = sim.objects[0].model.triangles().len();
    let height = (hi.z - lo.z).max(1.0);
    let mid_z = 0.5 * (hi.z + lo.z);
    let mut scratch = CutScratch::default();
    let x = 0.5 * (lo.x + hi.x) + 0.37;
    let mut openings = Vec::new();
    let mut y = lo.y - 3.0;
    while y < hi.y + 3.0 {
        let blade = |y: f32| {
            [
                Vec3::new(x, y, mid_z - height),
                Vec3::new(x, y, mid_z + height),
            ]
        };
        let sweep = BladeSweep {
            from_mm: blade(y),
            to_mm: blade(y + 1.0),
        };
        let opening = sim.cut(0, &sweep, &mut scratch);
        if !opening.is_empty() {
            openings.push(opening);
        }
        tick(&mut sim, ToolCommand::default());
        y += 1.0;
    }
    let model = &sim.objects[0].model;
    let tets = &model.tets().tets;
    println!(
        "{} openings, {} vertices, {} tets, surface {} -> {} triangles",
        openings.len(),
        model.node_count(),
        tets.len(),
        surface_before,
        model.triangles().len()
    );
    assert_eq!(pieces(tets, model.node_count()), 2, "not parted");
    assert!(
        model.triangles().len() > surface_before,
        "no cut face shown"
    );
    assert_closed_surface(model.triangles());
    // It still steps.
    for _ in 0..300 {
        tick(&mut sim, ToolCommand::default());
    }
    assert!(sim.objects[0].state.is_finite());
}

#[test]
fn a_sheet_stretched_past_its_strain_limit_tears_and_one_within_it_does_not() {
    let mut sim = pad_with(IntegratorName::SymplecticEuler, None);
    // Pull a strip of nodes near x = 0 up by 8 mm from outside (as a tie would), 0.4 s.
    let near: Vec<usize> = sim.objects[0]
        .model
        .rest_positions_mm()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.x.abs() < 1.5 && p.y.abs() < 4.0)
        .map(|(i, _)| i)
        .collect();
    assert!(!near.is_empty());
    let mut max_tears = Opening::default();
    let mut within = 0;
    for k in 0..400 {
        let z = 8.0 * ((k + 1) as f32 / 300.0).min(1.0);
        for &i in &near {
            let o = &mut sim.objects[0];
            o.state.positions_mm[i].z = z;
            o.state.velocities_mm_s[i] = Vec3::zeros();
        }
        sim.note_state_changed();
        within += sim.tear(0, 10.0).new_vertices();
        let torn = sim.tear(0, 0.3);
        if !torn.is_empty() {
            max_tears = torn;
            break;
        }
        tick(&mut sim, ToolCommand::default());
    }
    assert_eq!(within, 0, "a strain limit of 1000% tore");
    assert!(
        !max_tears.is_empty(),
        "an 8 mm pull never stretched a spring past 30%"
    );
    println!("tore: {} vertices split", max_tears.new_vertices());
}

/// `worlds/cut.toml` (tool 0 a scalpel, edge from 2 mm above to 9 mm below its origin, device origin at world
/// x = 0.5) as it ships.
fn cut_world() -> Sim {
    Sim::new(&shipped("cut.toml")).unwrap()
}

/// The scalpel's hand at device `y_mm`, its origin `height_mm` above the rest surface.
fn blade_at(y_mm: f32, height_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.0, y_mm, height_mm],
        ..ToolCommand::default()
    }
}

#[test]
fn a_scalpel_cuts_where_its_edge_sweeps_and_drags_against_its_motion() {
    let mut sim = cut_world();
    // Down from 10 mm to 1.5 mm above the surface (a plunge along the edge cuts nothing), then 10 mm along +y.
    let mut split = 0;
    for k in 0..300 {
        let h = 10.0 - 8.5 * (k + 1) as f32 / 300.0;
        let (out, report) = tick(&mut sim, blade_at(-5.0, h));
        split += report.vertices_split;
        assert!(!out.cutting, "the plunge cut");
    }
    for _ in 0..100 {
        split += tick(&mut sim, blade_at(-5.0, 1.5)).1.vertices_split;
    }
    assert_eq!(split, 0, "a plunge along the edge split {split} vertices");
    let (mut cutting_ticks, mut against) = (0, 0);
    for k in 0..500 {
        let y = -5.0 + 10.0 * (k + 1) as f32 / 500.0;
        let (out, report) = tick(&mut sim, blade_at(y, 1.5));
        split += report.vertices_split;
        if out.cutting {
            cutting_ticks += 1;
            against += usize::from(out.force_world_n.y < -0.05);
        }
    }
    // The hand stops: the tool settles onto it, the drag fading, never flipping tick to tick (a drag that
    // flipped with the tool's own last motion made a still hand's scalpel chatter).
    let mut out = ToolOutput::default();
    let mut flips = 0;
    for _ in 0..50 {
        let last = out.force_world_n[1];
        out = tick(&mut sim, blade_at(5.0, 1.5)).0;
        flips += usize::from(last * out.force_world_n[1] < 0.0);
    }
    assert_eq!(
        flips, 0,
        "the drag flipped {flips} times while the hand held still"
    );
    println!(
        "10 mm line: {split} vertices split, cutting on {cutting_ticks} ticks, dragged back on {against}"
    );
    assert!(split >= 8, "a 10 mm line split {split} vertices");
    assert!(
        cutting_ticks > 100 && against == cutting_ticks,
        "the drag did not oppose the motion"
    );
    assert!(!out.cutting, "a still edge cut");
}

#[test]
fn a_scalpel_that_joins_with_its_edge_in_the_tissue_cuts_nothing_on_its_way_to_the_hand() {
    let mut sim = cut_world();
    // The hand is already down, 20 mm from the device origin: the tool enters clear of the tissue and is
    // dragged to it through the sheet. That path is not the surgeon's cut.
    let mut split = 0;
    for _ in 0..400 {
        split += tick(&mut sim, blade_at(-20.0, 1.5)).1.vertices_split;
    }
    assert_eq!(split, 0, "the drag to the hand cut {split} vertices");
    // Once there, it cuts as it moves.
    for k in 0..300 {
        let y = -20.0 + 6.0 * (k + 1) as f32 / 300.0;
        split += tick(&mut sim, blade_at(y, 1.5)).1.vertices_split;
    }
    assert!(
        split >= 4,
        "a 6 mm line after joining split {split} vertices"
    );
}

#[test]
fn a_sheet_with_a_tear_strain_tears_under_a_hard_grasped_pull_and_one_without_does_not() {
    let pull = |tear: Option<f32>| -> (u32, u32, usize) {
        let mut sim = pad_edited(IntegratorName::SymplecticEuler, strong_grasper(), |w| {
            let material = &mut w.objects[0].material;
            assert_eq!(material.tear_strain, None);
            if tear.is_some() {
                material.tear_strain = tear;
            }
        });
        for k in 0..400 {
            let depth = -6.0 + 8.0 * (k + 1) as f32 / 400.0;
            tick(&mut sim, tool_at(0.0, depth, false));
        }
        for _ in 0..100 {
            tick(&mut sim, tool_at(0.0, 2.0, true));
        }
        // Lift the grasped sheet 12 mm over 1 s, and hold.
        let (mut torn, mut split) = (0, 0);
        for k in 0..1500 {
            let lift = 12.0 * ((k + 1) as f32 / 1000.0).min(1.0);
            let (_, report) = tick(&mut sim, tool_at(0.0, 2.0 - lift, true));
            assert!(
                report.seams_torn <= 32,
                "{} springs torn in one tick",
                report.seams_torn
            );
            torn += report.seams_torn;
            split += report.vertices_split;
        }
        let held = sim.tools[0].grasp().unwrap().attachments().len();
        (torn, split, held)
    };
    let (_, whole_split, whole_held) = pull(None);
    let (_, tough_split, _) = pull(Some(5.0));
    let (torn, split, held) = pull(Some(0.25));
    println!(
        "12 mm grasped lift: no tear strain {whole_split} split; 5.0 -> {tough_split} split; 0.25 -> {torn} springs torn, {split} vertices split, {held} of {whole_held} points still held"
    );
    assert_eq!(whole_split, 0);
    assert_eq!(tough_split, 0, "a 500% strain limit tore");
    assert!(
        torn > 0 && split > 0,
        "a 25% strain limit never tore under a 12 mm lift"
    );
}

/// Scissors' hand at device (0.5, `y_mm`), hinge `height_mm` above the rest surface, the button closing them or
/// not (0.5 mm off the device origin's x: the blades' plane does not run along a row of the pad's vertices).
fn scissors_at(y_mm: f32, height_mm: f32, closed: bool) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.5, y_mm, height_mm],
        jaws: JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    }
}

/// Snip at device `y_mm` (hinge `height_mm` above the surface): go there open (100 ticks), close for 200 ticks,
/// open for 100, stepping tool `tool` of `tools`, `on_tick` after each tick. The vertices split.
fn snip(
    sim: &mut Sim,
    tool: usize,
    tools: usize,
    y_mm: f32,
    height_mm: f32,
    mut on_tick: impl FnMut(&ToolOutput, &StepReport),
) -> u32 {
    let mut split = 0;
    let mut commands = vec![ToolCommand::default(); tools];
    let mut out = vec![ToolOutput::default(); tools];
    for k in 0..400 {
        commands[tool] = scissors_at(y_mm, height_mm, (100..300).contains(&k));
        let report = sim.step(0.001, &commands, &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[tool].force_world_n.iter().all(|c| c.is_finite()));
        on_tick(&out[tool], &report);
        split += report.vertices_split;
    }
    split
}

#[test]
fn scissors_cut_only_between_their_blades_as_they_close_and_a_line_of_snips_parts_the_sheet() {
    // The pad's tool (device origin at world x = -18) as scissors: 12 mm blades opened 40 degrees.
    let mut sim = pad_with(
        IntegratorName::SymplecticEuler,
        Some(InstrumentSpec::Scissors(ScissorsSpec {
            blade_length_mm: 12.0,
            // As the loader turns `open_angle_deg = 40.0` into radians.
            open_angle_rad: 40.0f32.to_radians(),
            ..ScissorsSpec::DEFAULT
        })),
    );
    let height_mm = 6.0;
    // Open scissors lowered through the sheet and moved 10 mm along it cut nothing.
    let mut split = 0;
    for k in 0..600 {
        let h = 20.0 - (20.0 - height_mm) * ((k + 1) as f32 / 400.0).min(1.0);
        split += tick(&mut sim, scissors_at(-30.0, h, false))
            .1
            .vertices_split;
    }
    for k in 0..500 {
        let y = -30.0 + 10.0 * (k + 1) as f32 / 500.0;
        let (out, report) = tick(&mut sim, scissors_at(y, height_mm, false));
        split += report.vertices_split;
        assert!(!out.cutting, "open scissors cut while moving");
    }
    assert_eq!(split, 0, "open scissors split {split} vertices");
    // One snip at y = 0: the cut lies between the blades, within the bite they span at the sheet.
    let first = sim.objects[0].model.node_count();
    let mut cutting = 0;
    let split = snip(&mut sim, 0, 1, 0.0, height_mm, |out, _| {
        cutting += usize::from(out.cutting);
    });
    let half_bite_mm = height_mm * (20.0f32 - 3.0).to_radians().tan();
    let model = &sim.objects[0].model;
    let (_, parents) = sim.objects[0].split_parents();
    let spread = parents
        .iter()
        .map(|&p| model.rest_positions_mm()[p as usize])
        .fold((f32::MAX, f32::MIN, 0.0f32), |(lo, hi, dx), p| {
            (lo.min(p.y), hi.max(p.y), dx.max((p.x + 17.5).abs()))
        });
    println!(
        "one snip: {split} vertices split (ids {first}..), parents' y {:.2}..{:.2} mm, |x| <= {:.2} mm; \
         bite +-{half_bite_mm:.2} mm; cutting on {cutting} ticks",
        spread.0, spread.1, spread.2
    );
    assert!(split >= 2, "a snip split {split} vertices");
    assert!(cutting > 0, "the output never said cutting");
    assert!(
        spread.0 >= -half_bite_mm - 1.5 && spread.1 <= half_bite_mm + 1.5 && spread.2 <= 1.5,
        "the snip cut outside its blades: {spread:?}"
    );
    // A line of snips 3 mm apart across the whole sheet (its fixed rim included) parts it in two.
    let mut y = -33.0;
    while y <= 33.0 {
        snip(&mut sim, 0, 1, y, height_mm, |_, _| {});
        y += 3.0;
    }
    let model = &sim.objects[0].model;
    assert_eq!(
        pieces(model.triangles(), model.node_count()),
        2,
        "a line of snips across the sheet did not part it"
    );
    for _ in 0..300 {
        tick(&mut sim, scissors_at(33.0, 20.0, false));
    }
    assert!(sim.objects[0].state.is_finite());
}

#[test]
fn scissors_snipping_into_the_tet_block_open_it_and_its_surface_stays_closed() {
    // worlds/cut.toml: tool 1 is a pair of scissors over the block (object 1), device origin at its centre.
    let mut sim = cut_world();
    assert!(sim.tools[1].instrument.scissors().is_some());
    let surface_before = sim.objects[1].model.triangles().len();
    let tets_before = sim.objects[1].model.tets().tets.len();
    let mut commands = vec![ToolCommand::default(); 2];
    let mut out = vec![ToolOutput::default(); 2];
    for k in 0..500 {
        let h = 20.0 - 14.0 * ((k + 1) as f32 / 400.0).min(1.0);
        commands[1] = scissors_at(-9.0, h, false);
        assert_eq!(sim.step(0.001, &commands, &mut out).faults, 0);
    }
    let mut split = 0;
    for k in 0..7 {
        split += snip(&mut sim, 1, 2, -9.0 + 3.0 * k as f32, 6.0, |_, _| {});
    }
    let model = &sim.objects[1].model;
    println!(
        "7 snips into the block: {split} vertices split, surface {surface_before} -> {} triangles",
        model.triangles().len()
    );
    assert!(split >= 4, "seven snips split {split} vertices");
    // The block's cut follows the blades (cut.toml: `cut = "follow-blade"`): the tetrahedra they cross split.
    assert!(
        model.tets().tets.len() > tets_before,
        "the snips split no tetrahedron: {} then {}",
        tets_before,
        model.tets().tets.len()
    );
    let rest = model.rest_positions_mm();
    for tet in &model.tets().tets {
        let [a, b, c, d] = tet.map(|v| rest[v as usize]);
        assert!(
            (b - a).cross(&(c - a)).dot(&(d - a)) > 0.0,
            "{tet:?} turned over"
        );
    }
    assert!(
        model.triangles().len() > surface_before,
        "the snips show no cut face"
    );
    assert_closed_surface(model.triangles());
    assert!(sim.objects[1].state.is_finite());
}

/// A free band 40 x 6 mm (1 mm cells, no anchors) with `tear_strain = 0.3`, fixed at x = -20: its world.
fn band_world() -> Sim {
    let dir = std::env::temp_dir().join(format!("sinew-band-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (nx, ny) = (41usize, 7usize);
    let mut obj = String::new();
    for j in 0..ny {
        for i in 0..nx {
            obj += &format!("v {} {} 0\n", i as f32 - 20.0, j as f32 - 3.0);
        }
    }
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let v = |i: usize, j: usize| j * nx + i + 1;
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j), v(i + 1, j + 1));
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j + 1), v(i, j + 1));
        }
    }
    std::fs::write(dir.join("band.obj"), obj).unwrap();
    let text = SheetWorldToml {
        scene: "band".into(),
        sim: SIM_DEFAULTS.into(),
        name: "band".into(),
        mesh: "band.obj".into(),
        integrator: "symplectic-euler".into(),
        dt_s: "0.001".into(),
        object_keys: "quant_margin_mm = 40.0\n".into(),
        material: "mass_kg = 0.05\nstiffness_n_per_mm = 0.015\ndamping_n_s_per_mm = 0.000003\n\
                   drag_per_s = 50.0\ntear_strain = 0.3\n"
            .into(),
        fixed: vec![fixed_plane([-20.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 0.01)],
        tool: sphere_tool("probe", "left", 1.0) + "device_origin_in_world_mm = [0.0, 0.0, 50.0]\n",
    }
    .text();
    let path = dir.join("band.toml");
    std::fs::write(&path, &text).unwrap();
    let sim = Sim::new(&load_world(&path).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    sim
}

#[test]
fn a_band_pulled_past_its_tear_strain_parts_and_not_before() {
    let mut sim = band_world();
    // Its far end (x = 20) is drawn out along +x, 16 mm (40% strain) over 16 s, as a hand holding it would.
    let end: Vec<usize> = sim.objects[0]
        .model
        .rest_positions_mm()
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.x - 20.0).abs() < 1e-3)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(end.len(), 7);
    let mut first_tear_mm = None;
    // The largest spring strain in the band after each tick (while nothing has torn).
    let max_strain = |sim: &Sim| {
        let o = &sim.objects[0];
        let springs = o.model.springs();
        (0..springs.len())
            .map(|s| {
                let (a, b, rest, _, _) = springs.get(s);
                (o.state.positions_mm[b] - o.state.positions_mm[a]).norm() / rest - 1.0
            })
            .fold(0.0f32, f32::max)
    };
    let mut strain_before_first_tear = 0.0;
    let mut out = [ToolOutput::default(); 2];
    for k in 0..16500 {
        let pulled_mm = 16.0 * ((k + 1) as f32 / 16000.0).min(1.0);
        let o = &mut sim.objects[0];
        for &i in &end {
            o.state.positions_mm[i].x = 20.0 + pulled_mm;
            o.state.velocities_mm_s[i] = Vec3::zeros();
        }
        sim.note_state_changed();
        let report = sim.step(0.001, &[], &mut out);
        assert_eq!(report.faults, 0, "the guard reset the band");
        if first_tear_mm.is_none() {
            if report.seams_torn > 0 {
                first_tear_mm = Some(pulled_mm);
            } else {
                strain_before_first_tear = max_strain(&sim);
            }
        }
    }
    let model = &sim.objects[0].model;
    let fragments = pieces(model.triangles(), model.node_count());
    // Parted: no chain of triangles joins the held end to the pulled end any more.
    let (held, pulled) = (
        model
            .rest_positions_mm()
            .iter()
            .position(|p| p.x == -20.0)
            .unwrap() as u32,
        end[0] as u32,
    );
    let mut joined = model.triangles().to_vec();
    joined.push([held, pulled, pulled]);
    let parted = pieces(&joined, model.node_count()) < fragments;
    println!(
        "band: first tear at {first_tear_mm:?} mm of pull ({:.0}% on average; the most strained spring at \
         {:.1}% after the tick before), parted {parted}, {fragments} pieces at 16 mm",
        first_tear_mm.unwrap_or(0.0) / 40.0 * 100.0,
        strain_before_first_tear * 100.0
    );
    first_tear_mm.expect("a 40% stretch never tore a band with a 30% limit");
    // Nothing tore while every spring was within the limit; the band tore as its most strained spring (at the
    // clamped end's corners, where the strain runs highest) passed it.
    assert!(
        (0.27..=0.3).contains(&strain_before_first_tear),
        "the band tore with its springs at most {strain_before_first_tear} strained"
    );
    assert!(parted, "the band did not part");
    assert!(sim.objects[0].state.is_finite());
}

#[test]
fn a_tet_block_pulled_past_its_tear_strain_tears_and_its_surface_stays_closed() {
    let mut world = shipped("tet_block.toml");
    assert_eq!(world.objects[0].material.tear_strain, None);
    world.objects[0].material.tear_strain = Some(0.3);
    let mut sim = Sim::new(&world).unwrap();
    let surface_before = sim.objects[0].model.triangles().len();
    // A patch of the top face (within 4 mm of its centre) is drawn 10 mm up over 1 s, as a grasp would.
    let patch: Vec<usize> = sim.objects[0]
        .model
        .rest_positions_mm()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.z > -0.01 && p.x.abs() < 4.0 && p.y.abs() < 4.0)
        .map(|(i, _)| i)
        .collect();
    assert!(!patch.is_empty());
    let (mut torn, mut split) = (0, 0);
    for k in 0..1500 {
        let z = 10.0 * ((k + 1) as f32 / 1000.0).min(1.0);
        let o = &mut sim.objects[0];
        for &i in &patch {
            o.state.positions_mm[i].z = z;
            o.state.velocities_mm_s[i] = Vec3::zeros();
        }
        sim.note_state_changed();
        let report = tick(&mut sim, ToolCommand::default()).1;
        torn += report.seams_torn;
        split += report.vertices_split;
    }
    let model = &sim.objects[0].model;
    println!(
        "block: {torn} faces torn, {split} vertices split, surface {surface_before} -> {} triangles",
        model.triangles().len()
    );
    assert!(
        torn > 0 && split > 0,
        "a 10 mm pull on a 10 mm block never tore it"
    );
    assert!(
        model.triangles().len() > surface_before,
        "no torn face shows"
    );
    assert_closed_surface(model.triangles());
    assert!(sim.objects[0].state.is_finite());
}

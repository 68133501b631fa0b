//! A malformed world is refused with an error naming the file, the key and the line, and the server binary
//! refuses to start with it.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use std::path::{Path, PathBuf};

use common::world_toml::{SheetWorldToml, fixed_box, sphere_tool};
use sinew_server::world::{WorldError, load_world};

/// A 3 x 3 node sheet, 2 mm cells, on z = 0.
const GRID_OBJ: &str = "v 0 0 0\nv 2 0 0\nv 4 0 0\nv 0 2 0\nv 2 2 0\nv 4 2 0\nv 0 4 0\nv 2 4 0\nv 4 4 0\n\
f 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\nf 4 5 8\nf 4 8 7\nf 5 6 9\nf 5 9 8\n";

/// The world every case edits: the 3 x 3 node sheet (`sheet.obj`), its x = 0 edge fixed, one 1 mm probe.
fn good_world() -> String {
    SheetWorldToml {
        scene: "test".into(),
        sim: String::new(),
        name: "sheet".into(),
        mesh: "sheet.obj".into(),
        integrator: "symplectic-euler".into(),
        dt_s: "0.001".into(),
        object_keys: String::new(),
        material: "mass_kg = 0.01\nstiffness_n_per_mm = 0.01\ndamping_n_s_per_mm = 0.0\n\
                   anchor_stiffness_n_per_mm = 0.001\n"
            .into(),
        fixed: vec![fixed_box([-1.0, -1.0, -1.0], [0.5, 5.0, 1.0])],
        tool: sphere_tool("probe", "left", 1.0),
    }
    .text()
}

/// Write `world` (and the sheet mesh, or `mesh` if given) into a fresh directory; return the world path.
fn write_world(world: &str, mesh: Option<&str>) -> PathBuf {
    let dir = common::scratch_dir("sinew-world-test");
    std::fs::write(dir.join("sheet.obj"), mesh.unwrap_or(GRID_OBJ)).unwrap();
    let path = dir.join("world.toml");
    std::fs::write(&path, world).unwrap();
    path
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

fn refused(world: &str, mesh: Option<&str>) -> (WorldError, String, PathBuf) {
    let path = write_world(world, mesh);
    let error = load_world(&path).expect_err("world must be refused");
    let message = error.to_string();
    assert!(
        message.contains(&path.display().to_string()),
        "no file in: {message}"
    );
    (error, message, path)
}

#[test]
fn the_test_world_and_the_shipped_pad_load() {
    load_world(&write_world(&good_world(), None)).unwrap();
    let pad =
        load_world(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml")).unwrap();
    assert_eq!(pad.objects[0].mesh.positions_mm.len(), 4941);
    assert_eq!(pad.tools.len(), 2);
}

#[test]
fn a_missing_mesh_names_the_mesh_key_and_line() {
    let world = good_world().replace("sheet.obj", "nowhere.obj");
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(error, WorldError::Mesh { line, .. } if line == line_of(&world, "nowhere.obj"))
    );
    assert!(
        message.contains("objects[0].mesh") && message.contains("nowhere.obj"),
        "{message}"
    );
}

#[test]
fn negative_stiffness_names_the_key_and_line() {
    let world = good_world().replace("stiffness_n_per_mm = 0.01", "stiffness_n_per_mm = -0.5");
    let (error, message, _) = refused(&world, None);
    match error {
        WorldError::Invalid { line, key, .. } => {
            assert_eq!(key, "objects[0].material.stiffness_n_per_mm");
            assert_eq!(line, line_of(&world, "stiffness_n_per_mm = -0.5"));
        }
        other => panic!("wrong error {other:?}"),
    }
    assert!(message.contains("-0.5"), "{message}");
}

#[test]
fn an_unknown_key_names_the_key_and_line() {
    let world = good_world().replace(
        "damping_n_s_per_mm = 0.0",
        "damping_n_s_per_mm = 0.0\nstifness = 2.0",
    );
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(error, WorldError::Syntax { line, .. } if line == line_of(&world, "stifness")),
        "{message}"
    );
    assert!(message.contains("unknown field `stifness`"), "{message}");
}

#[test]
fn a_cut_mode_is_read_and_an_unknown_one_names_its_line_and_the_choices() {
    let good = good_world().replace(
        "damping_n_s_per_mm = 0.0",
        "damping_n_s_per_mm = 0.0\ncut = \"follow-blade\"",
    );
    let world = load_world(&write_world(&good, None)).unwrap();
    assert!(world.objects[0].material.cut_follows_blade);
    let facets = good.replace("\"follow-blade\"", "\"facets\"");
    let world = load_world(&write_world(&facets, None)).unwrap();
    assert!(!world.objects[0].material.cut_follows_blade);
    let world = load_world(&write_world(&good_world(), None)).unwrap();
    assert!(
        !world.objects[0].material.cut_follows_blade,
        "the default is facets"
    );
    let bad = good.replace("\"follow-blade\"", "\"zigzag\"");
    let (error, message, _) = refused(&bad, None);
    assert!(
        matches!(error, WorldError::Syntax { line, .. } if line == line_of(&bad, "zigzag")),
        "{message}"
    );
    assert!(
        message.contains("zigzag")
            && message.contains("follow-blade")
            && message.contains("facets"),
        "{message}"
    );
}

#[test]
fn a_tool_contact_is_read_and_an_unknown_one_names_its_line_and_the_choices() {
    let with = |value: &str| {
        let mut world = good_world();
        world = world.replacen(
            "[objects.material]",
            &format!("tool_contact = \"{value}\"\n[objects.material]"),
            1,
        );
        world
    };
    let good = with("nodes-and-triangles");
    assert!(good.contains("tool_contact"), "{good}");
    let world = load_world(&write_world(&good, None)).unwrap();
    assert!(world.objects[0].triangle_contact);
    let world = load_world(&write_world(&with("nodes"), None)).unwrap();
    assert!(!world.objects[0].triangle_contact);
    let world = load_world(&write_world(&good_world(), None)).unwrap();
    assert!(!world.objects[0].triangle_contact, "the default is nodes");
    let bad = with("faces");
    let (error, message, _) = refused(&bad, None);
    assert!(
        matches!(error, WorldError::Syntax { line, .. } if line == line_of(&bad, "\"faces\"")),
        "{message}"
    );
    assert!(
        message.contains("faces")
            && message.contains("nodes-and-triangles")
            && message.contains("`nodes`"),
        "{message}"
    );
}

#[test]
fn a_non_manifold_mesh_is_refused() {
    // A fourth triangle on the edge (1, 5) that two triangles already share.
    let mesh = format!("{GRID_OBJ}v 2 2 3\nf 1 5 10\n");
    let (error, message, _) = refused(&good_world(), Some(&mesh));
    assert!(
        matches!(error, WorldError::Mesh { line, .. } if line == line_of(&good_world(), "sheet.obj"))
    );
    assert!(
        message.contains("non-manifold") && message.contains("objects[0].mesh"),
        "{message}"
    );
}

#[test]
fn an_empty_mesh_is_refused() {
    let (error, message, _) = refused(&good_world(), Some("# nothing here\nv 0 0 0\n"));
    assert!(matches!(error, WorldError::Mesh { .. }));
    assert!(message.contains("empty"), "{message}");
}

#[test]
fn an_unstable_step_is_refused_with_the_bound() {
    let world = good_world().replace("mass_kg = 0.01", "mass_kg = 0.0000001");
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(error, WorldError::Invalid { ref key, .. } if key == "objects[0].dt_s"),
        "{message}"
    );
    assert!(message.contains("stability bound"), "{message}");
}

#[test]
fn a_device_bound_to_two_tools_is_refused() {
    let world = format!(
        "{}\n[[tools]]\nname = \"probe2\"\ndevice = \"left\"\nshape = {{ kind = \"sphere\", radius_mm = 1.0 }}\n",
        good_world()
    );
    let (error, _, _) = refused(&world, None);
    assert!(matches!(error, WorldError::Invalid { ref key, .. } if key == "tools[1].device"));
}

#[test]
fn the_server_refuses_to_start_with_a_malformed_world() {
    let world = good_world().replace("stiffness_n_per_mm = 0.01", "stiffness_n_per_mm = -0.5");
    let path = write_world(&world, None);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_sinew-server"))
        .arg("--world")
        .arg(&path)
        .args(["--listen", "tcp/127.0.0.1:0", "--duration-s", "1"])
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    let expected = format!(
        "{}:{}",
        path.display(),
        line_of(&world, "stiffness_n_per_mm = -0.5")
    );
    assert!(
        stderr.contains(&expected),
        "stderr does not name {expected}: {stderr}"
    );
    assert!(
        stderr.contains("objects[0].material.stiffness_n_per_mm"),
        "{stderr}"
    );
}

/// Two tetrahedra (tags 7 and 9) over five nodes, MSH 4.1 ASCII; `{Z}` is node 4's z (1 = valid, 0 = element
/// 7 flat).
const TWO_TETS_MSH: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 1 5\n3 1 0 5\n1\n2\n3\n4\n5\n\
0 0 0\n4 0 0\n0 4 0\n0 0 {Z}\n4 4 4\n$EndNodes\n$Elements\n1 2 7 9\n3 1 4 2\n7 1 2 3 4\n9 2 3 4 5\n$EndElements\n";

/// [`good_world`] on a `.msh` volume (written next to it) with density alone (32 mg: half the step).
fn msh_world() -> String {
    good_world()
        .replace("sheet.obj", "block.msh")
        .replace("mass_kg = 0.01", "density_kg_per_m3 = 1000.0")
        .replace("dt_s = 0.001", "dt_s = 0.0005")
}

/// Write `world` and `msh` (as `block.msh`) next to the sheet; return the world path.
fn write_msh_world(world: &str, msh: &str) -> PathBuf {
    let path = write_world(world, None);
    std::fs::write(path.with_file_name("block.msh"), msh).unwrap();
    path
}

fn msh_refused(world: &str, msh: &str) -> (WorldError, String) {
    let path = write_msh_world(world, msh);
    let error = load_world(&path).expect_err("world must be refused");
    let message = error.to_string();
    assert!(
        message.contains(&path.display().to_string()),
        "no file in: {message}"
    );
    (error, message)
}

fn invalid_key_and_line(error: &WorldError) -> (&str, usize) {
    match error {
        WorldError::Invalid { key, line, .. } => (key, *line),
        other => panic!("wrong error {other:?}"),
    }
}

#[test]
fn a_msh_volume_and_an_extruded_sheet_load_with_their_tetrahedra() {
    let world = load_world(&write_msh_world(
        &msh_world(),
        &TWO_TETS_MSH.replace("{Z}", "4"),
    ))
    .unwrap();
    let block = &world.objects[0];
    assert_eq!((block.tets.len(), block.mesh.triangles.len()), (2, 6));
    assert!(matches!(
        block.material.mass,
        sinew_server::world::MassSpec::Density { kg_per_m3, .. } if kg_per_m3 == 1000.0
    ));
    // The sheet extruded 1.5 mm in 2 layers: 3 x 8 triangles x 2 layers, and the fixed box (x <= 0.5) now
    // also holds the extruded nodes under the fixed edge.
    let extruded = good_world()
        .replace(
            "units = \"mm\"",
            "units = \"mm\"\nextrude = { thickness_mm = 1.5, layers = 2 }",
        )
        .replace("min_mm = [-1.0, -1.0, -1.0]", "min_mm = [-1.0, -1.0, -2.0]");
    let world = load_world(&write_world(&extruded, None)).unwrap();
    let sheet = &world.objects[0];
    assert_eq!(sheet.tets.len(), 48);
    assert_eq!(sheet.mesh.positions_mm.len(), 27);
    let model =
        sinew_server::tissue::MassSpringModel::build(sheet, sinew_server::tissue::Vec3::zeros());
    let fixed: Vec<[f32; 3]> = (0..model.node_count())
        .filter(|&i| model.is_fixed(i))
        .map(|i| sheet.mesh.positions_mm[i])
        .collect();
    assert_eq!(
        fixed.len(),
        9,
        "3 nodes on x = 0 in each of 3 layers: {fixed:?}"
    );
    assert!(fixed.iter().any(|p| p[2] == -1.5));
}

#[test]
fn extrude_on_a_msh_volume_is_refused() {
    let world = msh_world().replace(
        "units = \"mm\"",
        "units = \"mm\"\nextrude = { thickness_mm = 2.0 }",
    );
    let (error, message) = msh_refused(&world, &TWO_TETS_MSH.replace("{Z}", "4"));
    assert_eq!(
        invalid_key_and_line(&error),
        ("objects[0].extrude", line_of(&world, "extrude ="))
    );
    assert!(message.contains("already a volume"), "{message}");
}

#[test]
fn thickness_with_a_volume_mesh_is_refused() {
    let world = msh_world().replace(
        "density_kg_per_m3 = 1000.0",
        "density_kg_per_m3 = 1000.0\nthickness_mm = 2.0",
    );
    let (error, message) = msh_refused(&world, &TWO_TETS_MSH.replace("{Z}", "4"));
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "objects[0].material.thickness_mm",
            line_of(&world, "thickness_mm = 2.0")
        )
    );
    assert!(
        message.contains("give density_kg_per_m3 alone"),
        "{message}"
    );
}

#[test]
fn a_non_positive_extrusion_thickness_is_refused() {
    for thickness in ["0.0", "-1.0"] {
        let world = good_world().replace(
            "units = \"mm\"",
            &format!("units = \"mm\"\nextrude = {{ thickness_mm = {thickness}, layers = 2 }}"),
        );
        let (error, message, _) = refused(&world, None);
        assert_eq!(
            invalid_key_and_line(&error),
            (
                "objects[0].extrude.thickness_mm",
                line_of(&world, "extrude =")
            )
        );
        assert!(message.contains("positive"), "{message}");
    }
}

#[test]
fn extrusion_layers_outside_1_to_16_are_refused() {
    for layers in ["0", "17", "-3"] {
        let world = good_world().replace(
            "units = \"mm\"",
            &format!("units = \"mm\"\nextrude = {{ thickness_mm = 1.0, layers = {layers} }}"),
        );
        let (error, message, _) = refused(&world, None);
        assert_eq!(
            invalid_key_and_line(&error),
            ("objects[0].extrude.layers", line_of(&world, "extrude ="))
        );
        assert!(message.contains("1..=16"), "{message}");
    }
}

#[test]
fn tet_volume_on_a_surface_mesh_is_refused() {
    let world = good_world().replace(
        "anchor_stiffness_n_per_mm = 0.001",
        "anchor_stiffness_n_per_mm = 0.001\ntet_bulk_modulus_kpa = 50.0",
    );
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "objects[0].material.tet_bulk_modulus_kpa",
            line_of(&world, "tet_bulk_modulus_kpa")
        )
    );
    assert!(message.contains("needs tetrahedra"), "{message}");
}

#[test]
fn a_degenerate_tetrahedron_names_its_element_and_the_mesh_key() {
    let world = msh_world();
    let (error, message) = msh_refused(&world, &TWO_TETS_MSH.replace("{Z}", "0"));
    assert!(
        matches!(&error, WorldError::Mesh { key, line, .. }
            if key == "objects[0].mesh" && *line == line_of(&world, "block.msh")),
        "{message}"
    );
    assert!(message.contains("tetrahedron 7 is degenerate"), "{message}");
}

/// Every duration and rate is checked for its real range, not only its sign: `pose_timeout_s = 1e30` once
/// loaded and then panicked the sim thread (`cannot convert float seconds to Duration`), leaving a zombie.
#[test]
fn durations_and_rates_out_of_their_real_range_name_the_key_and_line() {
    let with_sim = |sim: &str| {
        good_world().replace(
            "scene = \"test\"\n",
            &format!("scene = \"test\"\n\n[sim]\n{sim}\n"),
        )
    };
    let cases = [
        ("pose_timeout_s = 1e30", "sim.pose_timeout_s"),
        ("pose_timeout_s = 1e-9", "sim.pose_timeout_s"),
        ("tick_hz = 1e-300", "sim.tick_hz"),
        ("tick_hz = 50.0", "sim.tick_hz"),
        ("publish_hz = 1e-300", "sim.publish_hz"),
        ("threads = 0", "sim.threads"),
        ("threads = 65", "sim.threads"),
    ];
    for (line, expected_key) in cases {
        let world = with_sim(line);
        let (error, message, _) = refused(&world, None);
        match error {
            WorldError::Invalid { key, line: at, .. } => {
                assert_eq!(key, expected_key, "{message}");
                assert_eq!(at, line_of(&world, line), "{message}");
            }
            other => panic!("`{line}`: wrong error {other:?}"),
        }
    }
    // A thread count in range loads as given; left out, the machine's share is used when the server starts.
    let world = load_world(&write_world(&with_sim("threads = 3"), None)).unwrap();
    assert_eq!(world.tissue_threads, Some(3));
    let world = load_world(&write_world(&good_world(), None)).unwrap();
    assert_eq!(world.tissue_threads, None);
    // A step so small that one tick would take a billion substeps.
    let world = good_world().replace("dt_s = 0.001", "dt_s = 1e-12");
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(&error, WorldError::Invalid { key, .. } if key == "objects[0].dt_s"),
        "{message}"
    );
    assert!(message.contains("substeps"), "{message}");
}

const EXERCISE: &str = r#"
[exercise]
name = "touch"
kind = "coordination"
time_limit_s = 30.0

[[exercise.targets]]
at_mm = [2.0, 2.0, 0.0]
radius_mm = 1.0
tool = "probe"

[[exercise.targets]]
at_mm = [4.0, 2.0, 0.0]
radius_mm = 1.0
tool = "probe"
"#;

#[test]
fn the_shipped_exercises_and_a_test_exercise_load() {
    let world = load_world(&write_world(&format!("{}{EXERCISE}", good_world()), None)).unwrap();
    let exercise = world.exercise.unwrap();
    assert_eq!(exercise.targets.len(), 2);
    assert_eq!(exercise.targets[1].tool, Some(0));
    for name in [
        "exercise_coordination.toml",
        "exercise_accurate_touch.toml",
        "exercise_stiffness_ranking.toml",
        "exercise_pattern_cutting.toml",
        "suture.toml",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../worlds")
            .join(name);
        let world = load_world(&path).unwrap();
        assert!(world.exercise.is_some(), "{name}");
    }
}

#[test]
fn a_bad_exercise_names_the_key_and_line_and_lists_what_would_do() {
    // A target naming a tool the world does not have.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replacen("tool = \"probe\"\n\n[[", "tool = \"grasper\"\n\n[[", 1)
    );
    let (error, message, _) = refused(&world, None);
    let (key, line) = invalid_key_and_line(&error);
    assert_eq!(key, "exercise.targets[0].tool");
    let header = line_of(&world, "[[exercise.targets]]");
    assert!(
        (header..=line_of(&world, "grasper")).contains(&line),
        "line {line}: {message}"
    );
    assert!(
        message.contains("grasper") && message.contains("tools: probe"),
        "{message}"
    );

    // A coordination target that names no tool.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replacen("tool = \"probe\"\n", "", 1)
    );
    let (error, _, _) = refused(&world, None);
    assert_eq!(invalid_key_and_line(&error).0, "exercise.targets[0].tool");

    // No time to do it in.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replace("time_limit_s = 30.0", "time_limit_s = 0.0")
    );
    let (error, _, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "exercise.time_limit_s",
            line_of(&world, "time_limit_s = 0.0")
        )
    );

    // Accurate touch without its depth limit.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replace("kind = \"coordination\"", "kind = \"accurate-touch\"")
    );
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.depth_limit_mm",
        "{message}"
    );

    // A kind that does not exist: the parser names the variants.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replace("\"coordination\"", "\"juggling\"")
    );
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(error, WorldError::Syntax { line, .. } if line == line_of(&world, "juggling")),
        "{message}"
    );
    assert!(message.contains("accurate-touch"), "{message}");

    // A suture exercise with three marks (it has an entry and an exit), and one with a depth limit.
    let suture = EXERCISE.replace("kind = \"coordination\"", "kind = \"suture\"");
    let three =
        format!("{suture}\n[[exercise.targets]]\nat_mm = [6.0, 2.0, 0.0]\nradius_mm = 1.0\n");
    let world = format!("{}{three}", good_world());
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.targets",
        "{message}"
    );
    assert!(
        message.contains("entry mark then the exit mark (got 3)"),
        "{message}"
    );
    let world = format!(
        "{}{}",
        good_world(),
        suture.replace(
            "time_limit_s = 30.0",
            "time_limit_s = 30.0\ndepth_limit_mm = 3.0"
        )
    );
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "exercise.depth_limit_mm",
            line_of(&world, "depth_limit_mm = 3.0")
        ),
        "{message}"
    );
    // Its two marks load.
    let world = load_world(&write_world(&format!("{}{suture}", good_world()), None)).unwrap();
    assert_eq!(
        world.exercise.unwrap().kind,
        sinew_server::scene::ExerciseKind::Suture
    );
    // A wound named with an object the world lacks, a coordination exercise naming a wound, and a wound
    // between an object and itself.
    let with_wound = |kind: &str, wound: &str| {
        format!(
            "{}{}",
            good_world(),
            EXERCISE.replace(
                "kind = \"coordination\"",
                &format!("kind = \"{kind}\"\nwound = {wound}")
            )
        )
    };
    let world = with_wound("suture", "[\"sheet\", \"liver\"]");
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        ("exercise.wound", line_of(&world, "wound = ")),
        "{message}"
    );
    assert!(message.contains("no object named `liver`"), "{message}");
    let world = with_wound("coordination", "[\"sheet\", \"sheet\"]");
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.wound",
        "{message}"
    );
    assert!(message.contains("only a suture exercise"), "{message}");
    let world = with_wound("suture", "[\"sheet\", \"sheet\"]");
    let (_, message, _) = refused(&world, None);
    assert!(message.contains("names one object twice"), "{message}");
    // Tied off with a knot: a suture exercise only.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replace(
            "kind = \"coordination\"",
            "kind = \"coordination\"\nknot = true"
        )
    );
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        ("exercise.knot", line_of(&world, "knot = true")),
        "{message}"
    );
    assert!(message.contains("only a suture exercise"), "{message}");
    let tied_off = load_world(&write_world(
        &format!(
            "{}{}",
            good_world(),
            suture.replace("time_limit_s = 30.0", "time_limit_s = 30.0\nknot = true")
        ),
        None,
    ))
    .unwrap();
    assert!(tied_off.exercise.unwrap().knot);

    // No targets at all.
    let world = format!(
        "{}\n[exercise]\nname = \"x\"\nkind = \"coordination\"\ntime_limit_s = 1.0\ntargets = []\n",
        good_world()
    );
    let (error, _, _) = refused(&world, None);
    assert_eq!(invalid_key_and_line(&error).0, "exercise.targets");
}

#[test]
fn a_bad_ranking_exercise_names_the_samples_key_and_the_objects() {
    let ranking = "\n[exercise]\nname = \"rank\"\nkind = \"stiffness-ranking\"\ntime_limit_s = 10.0\nsamples = [\"sheet\", \"liver\"]\n";
    let world = format!("{}{ranking}", good_world());
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error),
        ("exercise.samples", line_of(&world, "samples = "))
    );
    assert!(
        message.contains("liver") && message.contains("objects: sheet"),
        "{message}"
    );

    // One sample is no ranking.
    let world = format!("{}{}", good_world(), ranking.replace(", \"liver\"", ""));
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.samples",
        "{message}"
    );

    // Samples on a target exercise, and a ranking without samples.
    let world = format!(
        "{}{}",
        good_world(),
        EXERCISE.replace(
            "time_limit_s = 30.0",
            "time_limit_s = 30.0\nsamples = [\"sheet\"]"
        )
    );
    let (error, _, _) = refused(&world, None);
    assert_eq!(invalid_key_and_line(&error).0, "exercise.samples");
    let world = format!(
        "{}{}",
        good_world(),
        ranking.replace("samples = [\"sheet\", \"liver\"]\n", "")
    );
    let (error, _, _) = refused(&world, None);
    assert_eq!(invalid_key_and_line(&error).0, "exercise.samples");
}

/// Every bad instrument key is refused with its key and line; a good grasper loads with its values.
#[test]
fn bad_instrument_keys_name_the_key_and_line() {
    let tool_line = "shape = { kind = \"sphere\", radius_mm = 1.0 }";
    let with = |instrument: &str| {
        good_world().replace(
            tool_line,
            &format!("{tool_line}\ninstrument = {instrument}"),
        )
    };
    let good = with(
        "{ kind = \"grasper\", activation = \"angle\", close_below_deg = 5.0, open_above_deg = 15.0, slip_force_n = 0.5 }",
    );
    let world = load_world(&write_world(&good, None)).unwrap();
    let scissors = load_world(&write_world(
        &with("{ kind = \"scissors\", activation = \"angle\", blade_length_mm = 15.0, hinge_mm = [0.0, 0.0, 2.0] }"),
        None,
    ))
    .unwrap();
    let blades = scissors.tools[0].instrument.scissors().copied().unwrap();
    assert_eq!(blades.blade_length_mm, 15.0);
    assert_eq!(blades.hinge_mm, [0.0, 0.0, 2.0]);
    assert_eq!(
        blades.activation,
        sinew_server::world::GraspSpec::ANGLE_DEFAULT
    );
    let grasp = world.tools[0].instrument.grasp().copied().unwrap();
    assert_eq!(grasp.slip_force_n, 0.5);
    assert!(matches!(
        grasp.activation,
        sinew_server::world::JawActivation::Angle { close_below_rad, .. } if (close_below_rad - 5f32.to_radians()).abs() < 1e-6
    ));
    for (instrument, key, says) in [
        (
            "{ kind = \"probe\", slip_force_n = 0.5 }",
            "tools[0].instrument.slip_force_n",
            "a probe has no jaws",
        ),
        (
            "{ kind = \"scalpel\", edge_from_mm = [0.0, 0.0, 1.0], edge_to_mm = [0.0, 0.0, 1.05] }",
            "tools[0].instrument.edge_to_mm",
            "at least 0.1 mm",
        ),
        (
            "{ kind = \"scalpel\", edge_from_mm = [0.0, nan, 1.0] }",
            "tools[0].instrument.edge_from_mm",
            "finite",
        ),
        (
            "{ kind = \"scalpel\", cut_resistance_n = 0.2 }",
            "tools[0].instrument.cut_resistance_n",
            "[objects.material] cut_resistance_n",
        ),
        (
            "{ kind = \"scissors\", blade_length_mm = 0.5 }",
            "tools[0].instrument.blade_length_mm",
            "1 to 200 mm",
        ),
        (
            "{ kind = \"scissors\", open_angle_deg = 4.0 }",
            "tools[0].instrument.open_angle_deg",
            "more than 6",
        ),
        (
            "{ kind = \"scissors\", hinge_mm = [0.0, 0.0, inf] }",
            "tools[0].instrument.hinge_mm",
            "finite",
        ),
        (
            "{ kind = \"scissors\", edge_from_mm = [0.0, 0.0, 1.0] }",
            "tools[0].instrument.edge_from_mm",
            "scissors take",
        ),
        (
            "{ kind = \"scissors\", activation = \"angle\", close_below_deg = 20.0, open_above_deg = 10.0 }",
            "tools[0].instrument.open_above_deg",
            "hysteresis",
        ),
        (
            "{ kind = \"scalpel\", slip_force_n = 0.5 }",
            "tools[0].instrument.slip_force_n",
            "a scalpel takes",
        ),
        (
            "{ kind = \"grasper\", slip_force_n = -1.0 }",
            "tools[0].instrument.slip_force_n",
            "positive",
        ),
        (
            "{ kind = \"grasper\", jaw_length_mm = nan }",
            "tools[0].instrument.jaw_length_mm",
            "positive",
        ),
        (
            "{ kind = \"grasper\", activation = \"angle\", close_below_deg = 20.0, open_above_deg = 10.0 }",
            "tools[0].instrument.open_above_deg",
            "hysteresis",
        ),
        (
            "{ kind = \"grasper\", close_below_deg = 5.0 }",
            "tools[0].instrument.close_below_deg",
            "activation = \"angle\"",
        ),
        (
            "{ kind = \"grasper\", activation = \"angle\", button_mask = 2 }",
            "tools[0].instrument.button_mask",
            "activation = \"button\"",
        ),
        (
            "{ kind = \"grasper\", button_mask = 0 }",
            "tools[0].instrument.button_mask",
            "button bit",
        ),
        (
            "{ kind = \"grasper\", max_attachments = 1000 }",
            "tools[0].instrument.max_attachments",
            "1 to 256",
        ),
        (
            "{ kind = \"grasper\", bite_mm = 50.0 }",
            "tools[0].instrument.bite_mm",
            "0 to 10",
        ),
    ] {
        let world = with(instrument);
        let (error, message, _) = refused(&world, None);
        match error {
            WorldError::Invalid { line, key: got, .. } => {
                assert_eq!(got, key, "{instrument}: {message}");
                assert_eq!(line, line_of(&world, "instrument ="), "{message}");
            }
            other => panic!("{instrument}: wrong error {other:?}"),
        }
        assert!(message.contains(says), "{instrument}: {message}");
    }
    // A shaft: loads with its values, refused out of range by key and line.
    let shaft_line = "shaft = { radius_mm = 2.5, length_mm = 40.0 }";
    let shafted = good_world().replace(tool_line, &format!("{tool_line}\n{shaft_line}"));
    let world = load_world(&write_world(&shafted, None)).unwrap();
    assert_eq!(
        world.tools[0].shaft,
        Some(sinew_server::world::ShaftSpec {
            radius_mm: 2.5,
            length_mm: 40.0
        })
    );
    for (bad, key) in [
        ("radius_mm = 0.0", "tools[0].shaft.radius_mm"),
        ("length_mm = 5000.0", "tools[0].shaft.length_mm"),
    ] {
        let from = if key.ends_with("radius_mm") {
            "radius_mm = 2.5"
        } else {
            "length_mm = 40.0"
        };
        let world = shafted.replace(from, bad);
        let (error, message, _) = refused(&world, None);
        assert_eq!(
            invalid_key_and_line(&error),
            (key, line_of(&world, "shaft = ")),
            "{message}"
        );
    }
    // An unknown kind or key is a syntax error on its line.
    let world = with("{ kind = \"laser\" }");
    let (error, message, _) = refused(&world, None);
    assert!(
        matches!(error, WorldError::Syntax { line, .. } if line == line_of(&world, "laser")),
        "{message}"
    );
    let world = with("{ kind = \"grasper\", grip = 1.0 }");
    let (_, message, _) = refused(&world, None);
    assert!(message.contains("unknown field `grip`"), "{message}");
}

#[test]
fn a_tear_strain_out_of_range_is_refused_and_a_volume_takes_one() {
    let good = good_world().replace(
        "anchor_stiffness_n_per_mm = 0.001",
        "anchor_stiffness_n_per_mm = 0.001\ntear_strain = 0.5",
    );
    let world = load_world(&write_world(&good, None)).unwrap();
    assert_eq!(world.objects[0].material.tear_strain, Some(0.5));
    let bad = good.replace("tear_strain = 0.5", "tear_strain = 0.0");
    let (error, message, _) = refused(&bad, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "objects[0].material.tear_strain",
            line_of(&bad, "tear_strain = 0.0")
        )
    );
    assert!(message.contains("above 0"), "{message}");
    // A volume tears too.
    let volume = msh_world().replace(
        "density_kg_per_m3 = 1000.0",
        "density_kg_per_m3 = 1000.0\ntear_strain = 0.5",
    );
    let path = write_msh_world(&volume, &TWO_TETS_MSH.replace("{Z}", "4"));
    let world = load_world(&path).unwrap();
    assert_eq!(world.objects[0].material.tear_strain, Some(0.5));
}

#[test]
fn a_cut_resistance_burn_shrink_or_friction_out_of_range_is_refused_by_key_and_line() {
    let good = good_world().replace(
        "anchor_stiffness_n_per_mm = 0.001",
        "anchor_stiffness_n_per_mm = 0.001\ncut_resistance_n = 0.4\nburn_shrink = 0.2\nfriction_coefficient = 0.3",
    );
    let world = load_world(&write_world(&good, None)).unwrap();
    assert_eq!(world.objects[0].material.cut_resistance_n, 0.4);
    assert_eq!(world.objects[0].material.burn_shrink, 0.2);
    assert_eq!(world.objects[0].material.friction_coefficient, 0.3);
    assert_refused_on_its_line(
        &good,
        &[
            (
                "cut_resistance_n = 0.4",
                "cut_resistance_n = -1.0",
                "objects[0].material.cut_resistance_n",
                "0 to 5 N",
            ),
            (
                "burn_shrink = 0.2",
                "burn_shrink = 0.9",
                "objects[0].material.burn_shrink",
                "0 to 0.5",
            ),
            (
                "burn_shrink = 0.2",
                "burn_shrink = nan",
                "objects[0].material.burn_shrink",
                "0 to 0.5",
            ),
            (
                "friction_coefficient = 0.3",
                "friction_coefficient = 3.0",
                "objects[0].material.friction_coefficient",
                "0 to 2",
            ),
        ],
    );
}

/// Each case `(from, to, key, line_text, says)` replaces `from` with `to` in `good` (the sheet mesh beside it);
/// the world is refused naming `key` on the line holding `line_text`, with a message containing `says`.
fn assert_refused_by_key_and_line(good: &str, cases: &[(&str, &str, &str, &str, &str)]) {
    for &(from, to, key, line_text, says) in cases {
        assert!(good.contains(from), "{from}");
        let bad = good.replacen(from, to, 1);
        let (error, message, _) = refused(&bad, None);
        assert_eq!(
            invalid_key_and_line(&error),
            (key, line_of(&bad, line_text)),
            "{message}"
        );
        assert!(message.contains(says), "{message}");
    }
}

/// [`good_world`]'s sheet extruded into a 1 mm volume of corotational finite elements.
fn fem_world() -> String {
    good_world()
        .replace(
            "units = \"mm\"",
            "units = \"mm\"\nextrude = { thickness_mm = 1.0, layers = 1 }\nmodel = \"fem-corotational\"",
        )
        .replace("symplectic-euler", "implicit-euler")
        .replace(
            "stiffness_n_per_mm = 0.01",
            "youngs_modulus_kpa = 5.0\npoisson_ratio = 0.45",
        )
}

#[test]
fn finite_element_keys_are_checked_by_key_and_line() {
    let good = fem_world();
    let world = load_world(&write_world(&good, None)).unwrap();
    let fem = world.objects[0].material.fem.expect("finite elements");
    assert!((fem.youngs_modulus_n_per_mm2 - 5e-3).abs() < 1e-9);
    assert_eq!((fem.poisson_ratio, fem.corotated), (0.45, true));
    assert_eq!(world.objects[0].material.stiffness_n_per_mm, 0.0);
    // Each: what replaces what in the good world, the key named, and the line it names (by its text).
    let cases: [(&str, &str, &str, &str, &str); 7] = [
        (
            "extrude = { thickness_mm = 1.0, layers = 1 }\n",
            "",
            "objects[0].model",
            "model = ",
            "needs tetrahedra",
        ),
        (
            "youngs_modulus_kpa = 5.0",
            "youngs_modulus_kpa = 5.0\nstiffness_n_per_mm = 0.01",
            "objects[0].material.stiffness_n_per_mm",
            "stiffness_n_per_mm",
            "remove stiffness_n_per_mm",
        ),
        (
            "youngs_modulus_kpa = 5.0\npoisson_ratio = 0.45",
            "",
            "objects[0].material.youngs_modulus_kpa",
            "name = \"sheet\"",
            "needs youngs_modulus_kpa and poisson_ratio",
        ),
        (
            "poisson_ratio = 0.45",
            "poisson_ratio = 0.5",
            "objects[0].material.poisson_ratio",
            "poisson_ratio",
            "0 to 0.499",
        ),
        (
            "youngs_modulus_kpa = 5.0",
            "youngs_modulus_kpa = -5.0",
            "objects[0].material.youngs_modulus_kpa",
            "youngs_modulus_kpa",
            "above 0",
        ),
        (
            "poisson_ratio = 0.45",
            "",
            "objects[0].material.poisson_ratio",
            "youngs_modulus_kpa",
            "needs poisson_ratio",
        ),
        (
            "implicit-euler",
            "xpbd",
            "objects[0].integrator",
            "integrator = ",
            "force-based integrator",
        ),
    ];
    assert_refused_by_key_and_line(&good, &cases);
    // A mass-spring object with neither a stiffness nor a modulus names the stiffness.
    let bare = good_world().replace("stiffness_n_per_mm = 0.01\n", "");
    let (error, message, _) = refused(&bare, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "objects[0].material.stiffness_n_per_mm",
            line_of(&bare, "name = \"sheet\"")
        )
    );
    assert!(message.contains("youngs_modulus_kpa"), "{message}");
}

#[test]
fn calibrated_springs_take_youngs_modulus_and_check_what_a_network_can_be() {
    // A volume: springs from Lloyd et al.'s fit, the per-tetrahedron volume term for the rest of nu.
    let volume = fem_world().replace("model = \"fem-corotational\"", "model = \"mass-spring\"");
    let world = load_world(&write_world(&volume, None)).unwrap();
    let calibration = world.objects[0].material.calibrated.expect("calibrated");
    assert_eq!(
        (calibration.poisson_ratio, calibration.thickness_mm),
        (0.45, 0.0)
    );
    assert!(world.objects[0].material.fem.is_none());
    let model = sinew_server::tissue::MassSpringModel::build(&world.objects[0], Default::default());
    let mu = 5e-3 / 2.9;
    assert!((model.tets().bulk_modulus_n_per_mm2 - 8.0 * mu).abs() < 1e-6);
    assert!(model.springs().stiffness_n_per_mm.iter().all(|&k| k >= 0.0));
    assert!(model.springs().stiffness_n_per_mm.iter().any(|&k| k > 0.0));
    // Below a network's own 1/4, a volume is refused.
    let soft = volume.replace("poisson_ratio = 0.45", "poisson_ratio = 0.2");
    let (error, message, _) = refused(&soft, None);
    assert_eq!(
        invalid_key_and_line(&error),
        (
            "objects[0].material.poisson_ratio",
            line_of(&soft, "poisson_ratio")
        )
    );
    assert!(message.contains("fem-corotational"), "{message}");

    // A sheet: its thickness sets the stiffness, and its ratio can only be 1/3.
    let sheet = good_world().replace(
        "stiffness_n_per_mm = 0.01",
        "youngs_modulus_kpa = 20.0\npoisson_ratio = 0.333\nthickness_mm = 2.0",
    );
    let world = load_world(&write_world(&sheet, None)).unwrap();
    let calibration = world.objects[0].material.calibrated.expect("calibrated");
    assert_eq!(calibration.thickness_mm, 2.0);
    let model = sinew_server::tissue::MassSpringModel::build(&world.objects[0], Default::default());
    // The 2 mm grid's right triangles: every edge gets some stiffness, of the order of E t from each triangle.
    let k = &model.springs().stiffness_n_per_mm;
    assert!(k.iter().all(|&k| k > 0.0 && k < 2.0 * 20e-3 * 2.0), "{k:?}");
    assert_refused_by_key_and_line(
        &sheet,
        &[
            (
                "poisson_ratio = 0.333",
                "poisson_ratio = 0.45",
                "objects[0].material.poisson_ratio",
                "poisson_ratio",
                "1/3",
            ),
            (
                "thickness_mm = 2.0",
                "",
                "objects[0].material.thickness_mm",
                "youngs_modulus_kpa",
                "need thickness_mm",
            ),
            (
                "youngs_modulus_kpa = 20.0",
                "youngs_modulus_kpa = 20.0\nstiffness_n_per_mm = 0.01",
                "objects[0].material.stiffness_n_per_mm",
                "stiffness_n_per_mm",
                "not both",
            ),
        ],
    );
}

#[test]
fn a_material_preset_fills_modulus_ratio_and_density_and_keys_beside_it_win() {
    let presets = sinew_server::world::material_presets().unwrap();
    let liver = &presets["liver"];
    // `fem_world()`'s [objects.material] table replaced by a preset name.
    let table_start = fem_world().find("[objects.material]").unwrap();
    let table_end = fem_world().find("[[objects.fixed]]").unwrap();
    let named = format!(
        "{}{}",
        &fem_world()[..table_start],
        &fem_world()[table_end..]
    )
    .replace(
        "model = \"fem-corotational\"",
        "model = \"fem-corotational\"\nmaterial = \"liver\"",
    );
    let world = load_world(&write_world(&named, None)).unwrap();
    let material = &world.objects[0].material;
    let fem = material.fem.expect("finite elements");
    assert!((fem.youngs_modulus_n_per_mm2 - liver.youngs_modulus_kpa * 1e-3).abs() < 1e-9);
    assert_eq!(fem.poisson_ratio, liver.poisson_ratio);
    assert!(matches!(
        material.mass,
        sinew_server::world::MassSpec::Density { kg_per_m3, .. } if kg_per_m3 == liver.density_kg_per_m3
    ));
    // A table with a preset: the keys given replace the preset's.
    let tuned = named.replace(
        "material = \"liver\"",
        "material = { preset = \"liver\", youngs_modulus_kpa = 4.0, drag_per_s = 20.0 }",
    );
    let world = load_world(&write_world(&tuned, None)).unwrap();
    let material = &world.objects[0].material;
    assert!((material.fem.unwrap().youngs_modulus_n_per_mm2 - 4e-3).abs() < 1e-9);
    assert_eq!(material.drag_per_s, 20.0);
    // An unknown preset names the line and lists the presets; a sheet cannot take one.
    let unknown = named.replace("\"liver\"", "\"spleen\"");
    let (error, message, _) = refused(&unknown, None);
    assert_eq!(
        invalid_key_and_line(&error),
        ("objects[0].material.preset", line_of(&unknown, "spleen"))
    );
    assert!(message.contains("fat, liver, muscle, skin"), "{message}");
    let sheet = named
        .replace("extrude = { thickness_mm = 1.0, layers = 1 }\n", "")
        .replace("model = \"fem-corotational\"\n", "");
    let (error, message, _) = refused(&sheet, None);
    assert_eq!(
        invalid_key_and_line(&error),
        ("objects[0].material.preset", line_of(&sheet, "liver"))
    );
    assert!(message.contains("volume"), "{message}");
}

#[test]
fn a_multi_rate_object_is_checked_by_key_and_line() {
    let good = fem_world().replace("dt_s = 0.001", "dt_s = 0.005\nstep_hz = 200");
    let world = load_world(&write_world(&good, None)).unwrap();
    assert_eq!(world.objects[0].ticks_per_step, 5);
    assert_eq!(
        load_world(&write_world(&fem_world(), None))
            .unwrap()
            .objects[0]
            .ticks_per_step,
        1
    );
    // At the tick rate itself: an ordinary object.
    let every_tick = fem_world().replace("dt_s = 0.001", "dt_s = 0.001\nstep_hz = 1000");
    let world = load_world(&write_world(&every_tick, None)).unwrap();
    assert_eq!(world.objects[0].ticks_per_step, 1);
    // Each: what replaces what in the good world, the key named, the line it names (by its text), and what
    // the message says.
    let cases: [(&str, &str, &str, &str, &str); 6] = [
        (
            "step_hz = 200",
            "step_hz = 300",
            "objects[0].step_hz",
            "step_hz",
            "whole number",
        ),
        (
            "step_hz = 200",
            "step_hz = 2000",
            "objects[0].step_hz",
            "step_hz",
            "no higher than",
        ),
        (
            "step_hz = 200",
            "step_hz = 5",
            "objects[0].step_hz",
            "step_hz",
            "at most 100",
        ),
        (
            "dt_s = 0.005",
            "dt_s = 0.006",
            "objects[0].dt_s",
            "dt_s",
            "step period",
        ),
        (
            "step_hz = 200",
            "step_hz = 200\nregion = { threshold_mm = 0.01 }",
            "objects[0].step_hz",
            "step_hz",
            "region",
        ),
        (
            "poisson_ratio = 0.45",
            "poisson_ratio = 0.45\nburn_shrink = 0.2",
            "objects[0].step_hz",
            "step_hz",
            "burn_shrink",
        ),
    ];
    assert_refused_by_key_and_line(&good, &cases);
}

/// A needle driver loads with its needle; each bad key is refused by key and line; the material's puncture keys
/// load and are refused out of range the same way.
#[test]
fn a_needle_driver_and_the_puncture_keys_load_and_bad_ones_name_the_key_and_line() {
    let tool_line = "shape = { kind = \"sphere\", radius_mm = 1.0 }";
    let with = |instrument: &str| {
        good_world().replace(
            tool_line,
            &format!("{tool_line}\ninstrument = {instrument}"),
        )
    };
    let world = load_world(&write_world(
        &with("{ kind = \"needle_driver\", needle_radius_mm = 8.0, needle_sweep_deg = 135.0, grasp_at_deg = 60.0 }"),
        None,
    ))
    .unwrap();
    let driver = *world.tools[0].instrument.needle_driver().unwrap();
    assert_eq!(driver.arc.radius_mm(), 8.0);
    assert!((driver.arc.sweep_rad() - 135f32.to_radians()).abs() < 1e-6);
    assert!((driver.grasp_at_rad - 60f32.to_radians()).abs() < 1e-6);
    assert_eq!(driver.diameter_mm, 0.5);
    // Without grasp_at_deg, a third of the way from the tail of the needle given.
    let world = load_world(&write_world(
        &with("{ kind = \"needle_driver\", needle_sweep_deg = 180.0 }"),
        None,
    ))
    .unwrap();
    let driver = *world.tools[0].instrument.needle_driver().unwrap();
    assert!((driver.grasp_at_rad - 60f32.to_radians()).abs() < 1e-6);
    assert_eq!(driver.thread.length_mm, 150.0, "the default thread");
    assert_eq!(driver.thread.segments, 64);
    let world = load_world(&write_world(
        &with("{ kind = \"needle_driver\", thread_length_mm = 200.0, thread_segments = 100 }"),
        None,
    ))
    .unwrap();
    let driver = *world.tools[0].instrument.needle_driver().unwrap();
    assert_eq!(
        (driver.thread.length_mm, driver.thread.segments),
        (200.0, 100)
    );
    let world = load_world(&write_world(
        &with("{ kind = \"needle_driver\", thread_length_mm = 0.0 }"),
        None,
    ))
    .unwrap();
    assert!(
        !world.tools[0]
            .instrument
            .needle_driver()
            .unwrap()
            .thread
            .is_some()
    );
    for (instrument, key, says) in [
        (
            "{ kind = \"needle_driver\", needle_radius_mm = 0.5 }",
            "tools[0].instrument.needle_radius_mm",
            "2 to 50 mm",
        ),
        (
            "{ kind = \"needle_driver\", needle_sweep_deg = 300.0 }",
            "tools[0].instrument.needle_sweep_deg",
            "30 to 270",
        ),
        (
            "{ kind = \"needle_driver\", needle_diameter_mm = 4.0 }",
            "tools[0].instrument.needle_diameter_mm",
            "at most 3 mm",
        ),
        (
            "{ kind = \"needle_driver\", needle_sweep_deg = 120.0, grasp_at_deg = 100.0 }",
            "tools[0].instrument.grasp_at_deg",
            "behind its point",
        ),
        (
            "{ kind = \"needle_driver\", slip_force_n = 0.5 }",
            "tools[0].instrument.slip_force_n",
            "a needle driver takes",
        ),
        (
            "{ kind = \"needle_driver\", thread_segments = 3 }",
            "tools[0].instrument.thread_segments",
            "4 to 512",
        ),
        (
            "{ kind = \"needle_driver\", thread_length_mm = 5.0 }",
            "tools[0].instrument.thread_length_mm",
            "10 to 1000 mm",
        ),
        (
            "{ kind = \"needle_driver\", thread_length_mm = 300.0 }",
            "tools[0].instrument.thread_length_mm",
            "at most 2.5 mm each",
        ),
        (
            "{ kind = \"needle_driver\", thread_length_mm = 150.0, thread_segments = 32 }",
            "tools[0].instrument.thread_segments",
            "segments of 4.69 mm",
        ),
    ] {
        let world = with(instrument);
        let (error, message, _) = refused(&world, None);
        assert_eq!(
            invalid_key_and_line(&error),
            (key, line_of(&world, "instrument =")),
            "{instrument}: {message}"
        );
        assert!(message.contains(says), "{instrument}: {message}");
    }
    let good = good_world().replace(
        "anchor_stiffness_n_per_mm = 0.001",
        "anchor_stiffness_n_per_mm = 0.001\npuncture_force_n = 3.0\npuncture_max_angle_deg = 30.0\nneedle_friction = 0.3\nsuture_tear_n = 3.7",
    );
    let world = load_world(&write_world(&good, None)).unwrap();
    let puncture = world.objects[0].material.puncture;
    assert_eq!(puncture.force_n, 3.0);
    assert!((puncture.max_angle_rad - 30f32.to_radians()).abs() < 1e-6);
    assert_eq!(puncture.needle_friction, 0.3);
    assert_eq!(puncture.suture_tear_n, Some(3.7));
    assert_refused_on_its_line(
        &good,
        &[
            (
                "puncture_force_n = 3.0",
                "puncture_force_n = 0.0",
                "objects[0].material.puncture_force_n",
                "0.05 to 50 N",
            ),
            (
                "puncture_max_angle_deg = 30.0",
                "puncture_max_angle_deg = 90.0",
                "objects[0].material.puncture_max_angle_deg",
                "1 to 89 degrees",
            ),
            (
                "needle_friction = 0.3",
                "needle_friction = nan",
                "objects[0].material.needle_friction",
                "0 to 2",
            ),
            (
                "suture_tear_n = 3.7",
                "suture_tear_n = 0.0",
                "objects[0].material.suture_tear_n",
                "0.1 to 50 N",
            ),
        ],
    );
}

/// Each case `(from, to, key, says)` replaces `from` with `to` in `good`: the world is refused naming `key` on
/// the line of `to`, with a message containing `says`.
fn assert_refused_on_its_line(good: &str, cases: &[(&str, &str, &str, &str)]) {
    for &(from, to, key, says) in cases {
        assert!(good.contains(from), "{from}");
        let bad = good.replace(from, to);
        let (error, message, _) = refused(&bad, None);
        assert_eq!(
            invalid_key_and_line(&error),
            (key, line_of(&bad, to)),
            "{message}"
        );
        assert!(message.contains(says), "{message}");
    }
}

/// `worlds/exercise_pattern_cutting.toml` with `edit` applied, its mesh named by its full path.
fn pattern_world(edit: impl Fn(String) -> String) -> String {
    let worlds = Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds");
    let text = std::fs::read_to_string(worlds.join("exercise_pattern_cutting.toml")).unwrap();
    let mesh = worlds.join("meshes/pad.obj");
    edit(text.replace(
        "\"meshes/pad.obj\"",
        &format!("{:?}", mesh.display().to_string()),
    ))
}

#[test]
fn a_bad_pattern_names_the_key_and_line_and_says_why() {
    let shipped = pattern_world(|t| t);
    let pattern = load_world(&write_world(&shipped, None))
        .unwrap()
        .exercise
        .unwrap()
        .pattern
        .unwrap();
    assert_eq!(
        (
            pattern.object,
            pattern.inner_radius_mm,
            pattern.outer_radius_mm
        ),
        (0, 19.5, 20.5)
    );
    let cases: [(&str, &str, &str, &str); 6] = [
        // (replace, with, key, in the message)
        (
            "outer_radius_mm = 20.5",
            "outer_radius_mm = 19.0",
            "exercise.pattern.outer_radius_mm",
            "more than the inner radius",
        ),
        (
            "inner_radius_mm = 19.5",
            "inner_radius_mm = -1.0",
            "exercise.pattern.inner_radius_mm",
            "positive",
        ),
        (
            "object = \"gauze\"",
            "object = \"liver\"",
            "exercise.pattern.object",
            "objects: gauze",
        ),
        (
            "centre_mm = [0.0, 0.0, 0.0]",
            "centre_mm = [0.0, 0.0, 30.0]",
            "exercise.pattern.centre_mm",
            "must lie on the sheet",
        ),
        // A pattern reaching the clips could never come free.
        (
            "outer_radius_mm = 20.5",
            "outer_radius_mm = 31.0",
            "exercise.pattern.outer_radius_mm",
            "never come free",
        ),
        // A pattern-cutting exercise with targets.
        (
            "[exercise.pattern]",
            "[[exercise.targets]]\nat_mm = [0.0, 0.0, 0.0]\nradius_mm = 1.0\n\n[exercise.pattern]",
            "exercise.targets",
            "a pattern, not targets",
        ),
    ];
    for (old, new, key, why) in cases {
        let world = pattern_world(|t| {
            assert!(t.contains(old), "{old}");
            t.replacen(old, new, 1)
        });
        let (error, message, _) = refused(&world, None);
        let (at, line) = invalid_key_and_line(&error);
        assert_eq!(at, key, "{message}");
        assert!(message.contains(why), "{message}");
        let section = line_of(&world, "[exercise.pattern]");
        assert!(
            line >= line_of(&world, "[exercise]") && line <= section + 5,
            "line {line}: {message}"
        );
    }
    // No pattern at all.
    let world = pattern_world(|t| t[..t.find("[exercise.pattern]").unwrap()].to_owned());
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.pattern",
        "{message}"
    );
    // A pattern on another kind of exercise.
    let world =
        pattern_world(|t| t.replace("kind = \"pattern-cutting\"", "kind = \"coordination\""));
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.pattern",
        "{message}"
    );
    assert!(
        message.contains("only a pattern-cutting exercise"),
        "{message}"
    );
    // A sheet without clips: nothing to cut the pattern free of.
    let world = pattern_world(|t| {
        let (from, to) = (t.find("# The clips").unwrap(), t.find("[[tools]]").unwrap());
        format!("{}{}", &t[..from], &t[to..])
    });
    let (error, message, _) = refused(&world, None);
    assert_eq!(
        invalid_key_and_line(&error).0,
        "exercise.pattern.object",
        "{message}"
    );
    assert!(message.contains("no fixed vertex"), "{message}");
}

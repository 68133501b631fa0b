//! A malformed world is refused with an error naming the file, the key and the line, and the server binary
//! refuses to start with it.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use sinew_server::world::{WorldError, load_world};

/// A 3 x 3 node sheet, 2 mm cells, on z = 0.
const GRID_OBJ: &str = "v 0 0 0\nv 2 0 0\nv 4 0 0\nv 0 2 0\nv 2 2 0\nv 4 2 0\nv 0 4 0\nv 2 4 0\nv 4 4 0\n\
f 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\nf 4 5 8\nf 4 8 7\nf 5 6 9\nf 5 9 8\n";

const GOOD_WORLD: &str = r#"scene = "test"

[[objects]]
name = "sheet"
mesh = "sheet.obj"
units = "mm"
integrator = "symplectic-euler"
dt_s = 0.001

[objects.material]
mass_kg = 0.01
stiffness_n_per_mm = 0.01
damping_n_s_per_mm = 0.0
anchor_stiffness_n_per_mm = 0.001

[[objects.fixed]]
kind = "box"
min_mm = [-1.0, -1.0, -1.0]
max_mm = [0.5, 5.0, 1.0]

[[tools]]
name = "probe"
device = "left"
shape = { kind = "sphere", radius_mm = 1.0 }
"#;

fn scratch_dir() -> PathBuf {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "sinew-world-test-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Write `world` (and the sheet mesh, or `mesh` if given) into a fresh directory; return the world path.
fn write_world(world: &str, mesh: Option<&str>) -> PathBuf {
    let dir = scratch_dir();
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
    load_world(&write_world(GOOD_WORLD, None)).unwrap();
    let pad =
        load_world(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml")).unwrap();
    assert_eq!(pad.objects[0].mesh.positions_mm.len(), 4941);
    assert_eq!(pad.tools.len(), 2);
}

#[test]
fn a_missing_mesh_names_the_mesh_key_and_line() {
    let world = GOOD_WORLD.replace("sheet.obj", "nowhere.obj");
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
    let world = GOOD_WORLD.replace("stiffness_n_per_mm = 0.01", "stiffness_n_per_mm = -0.5");
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
    let world = GOOD_WORLD.replace(
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
fn a_non_manifold_mesh_is_refused() {
    // A fourth triangle on the edge (1, 5) that two triangles already share.
    let mesh = format!("{GRID_OBJ}v 2 2 3\nf 1 5 10\n");
    let (error, message, _) = refused(GOOD_WORLD, Some(&mesh));
    assert!(
        matches!(error, WorldError::Mesh { line, .. } if line == line_of(GOOD_WORLD, "sheet.obj"))
    );
    assert!(
        message.contains("non-manifold") && message.contains("objects[0].mesh"),
        "{message}"
    );
}

#[test]
fn an_empty_mesh_is_refused() {
    let (error, message, _) = refused(GOOD_WORLD, Some("# nothing here\nv 0 0 0\n"));
    assert!(matches!(error, WorldError::Mesh { .. }));
    assert!(message.contains("empty"), "{message}");
}

#[test]
fn an_unstable_step_is_refused_with_the_bound() {
    let world = GOOD_WORLD.replace("mass_kg = 0.01", "mass_kg = 0.0000001");
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
        "{GOOD_WORLD}\n[[tools]]\nname = \"probe2\"\ndevice = \"left\"\nshape = {{ kind = \"sphere\", radius_mm = 1.0 }}\n"
    );
    let (error, _, _) = refused(&world, None);
    assert!(matches!(error, WorldError::Invalid { ref key, .. } if key == "tools[1].device"));
}

#[test]
fn the_server_refuses_to_start_with_a_malformed_world() {
    let world = GOOD_WORLD.replace("stiffness_n_per_mm = 0.01", "stiffness_n_per_mm = -0.5");
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

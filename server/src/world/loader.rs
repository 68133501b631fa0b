//! Validating a parsed world file into a [`World`]. Each check names the file, the key and the line.
//!
//! Here: the whole file (`[sim]`, the order of sections, the cross-checks) and the checking context. Each
//! section has its own file: `object.rs` (mesh, integrator, step rate, region), `material.rs` (presets, laws,
//! springs or elements, calibration), `fixed_and_ties.rs`, `tool.rs` (shape, shaft, coupling, instrument),
//! `exercise.rs`. The types it produces are the engine's descriptors ([`crate::scene`] and the layers it names); its error is
//! in [`super::world_error`].

mod exercise;
mod fixed_and_ties;
mod material;
mod needle_driver;
mod object;
mod tool;

use std::ops::Range;
use std::path::Path;

use toml::Spanned;

use super::file_format::WorldFile;
use super::world_error::WorldError;
use crate::collision::{ShaftSpec, ToolShapeSpec};
use crate::scene::{ToolSpec, World};
use crate::tissue::{FixedSelection, MassSpec, MaterialSpec, ObjectSpec, SpringCalibration};

/// Read, parse and validate a world file (mesh paths are relative to it).
pub fn load_world(path: &Path) -> Result<World, WorldError> {
    let text = std::fs::read_to_string(path).map_err(|e| WorldError::Read {
        file: path.to_owned(),
        message: e.to_string(),
    })?;
    parse_world(path, &text)
}

/// Names for an error message, comma-separated (what a key could have named instead).
fn listed<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names.collect::<Vec<_>>().join(", ")
}

/// The most ticks one step of a multi-rate object may span (`sim.tick_hz / step_hz`): 10 Hz at a 1 kHz tick.
pub const MAX_TICKS_PER_STEP: u32 = 100;

/// The most substeps an object may take in one tick: a smaller `dt_s` would only hang the tick.
const MAX_SUBSTEPS: f32 = 1000.0;

/// N/mm^2 per kPa.
const N_PER_MM2_PER_KPA: f32 = 1e-3;

/// Largest Young's modulus a world may give, kPa (1 GPa: bone is 10-20 GPa, but no tissue here is).
const MAX_YOUNGS_MODULUS_KPA: f32 = 1e6;

/// Largest Poisson's ratio a world may give (0.5 is incompressible: an infinite bulk modulus).
const MAX_POISSON_RATIO: f32 = 0.499;

/// Parse and validate world text; `path` names it in errors and anchors relative mesh paths.
pub fn parse_world(path: &Path, text: &str) -> Result<World, WorldError> {
    let file: WorldFile = toml::from_str(text).map_err(|e| WorldError::Syntax {
        file: path.to_owned(),
        line: e.span().map_or(1, |s| line_of(text, s.start)),
        message: e.message().trim().to_owned(),
    })?;
    let cx = Context { path, text };
    let base = path.parent().unwrap_or(Path::new("."));

    let scene = file.scene.get_ref().clone();
    if let Err(e) = sinew_protocol::keys::validate_segment("scene", &scene) {
        return Err(cx.invalid(&file.scene, "scene", e.to_string()));
    }
    let tick_hz = *file.sim.tick_hz.get_ref();
    cx.check(
        &file.sim.tick_hz,
        "sim.tick_hz",
        (100.0..=10_000.0).contains(&tick_hz),
        "must be in [100, 10000] Hz (haptic contact needs at least 100 Hz)",
    )?;
    let publish_hz = *file.sim.publish_hz.get_ref();
    cx.check(
        &file.sim.publish_hz,
        "sim.publish_hz",
        publish_hz >= 1.0 && publish_hz <= tick_hz,
        "must be in [1, sim.tick_hz] Hz",
    )?;
    let pose_timeout_s = *file.sim.pose_timeout_s.get_ref();
    cx.check(
        &file.sim.pose_timeout_s,
        "sim.pose_timeout_s",
        pose_timeout_s >= 1.0 / tick_hz && pose_timeout_s <= 10.0,
        "must be in [one tick, 10] s (a device silent this long has its tool released)",
    )?;
    let tissue_threads = match &file.sim.threads {
        Some(threads) => {
            let n = *threads.get_ref();
            cx.check(
                threads,
                "sim.threads",
                (1..=MAX_TISSUE_THREADS as i64).contains(&n),
                &format!(
                    "must be in [1, {MAX_TISSUE_THREADS}] (threads for the tissue passes, the tick's own included; \
                     leave it out for what the machine can spare)"
                ),
            )?;
            Some(n as usize)
        }
        None => None,
    };
    let gravity_mm_per_s2 = *file.sim.gravity_mm_per_s2.get_ref();
    cx.check(
        &file.sim.gravity_mm_per_s2,
        "sim.gravity_mm_per_s2",
        gravity_mm_per_s2
            .iter()
            .all(|c| c.is_finite() && c.abs() <= 1e6),
        "must be finite, each component within +-1e6 mm/s^2",
    )?;
    let margin = *file.collision.margin_mm.get_ref();
    cx.check(
        &file.collision.margin_mm,
        "collision.margin_mm",
        margin >= 0.0 && margin.is_finite(),
        "must be >= 0",
    )?;

    if file.objects.is_empty() {
        return Err(WorldError::Invalid {
            file: path.to_owned(),
            line: 1,
            key: "objects".into(),
            message: "a world needs at least one [[objects]] entry".into(),
        });
    }
    let tick_dt_s = (1.0 / tick_hz) as f32;
    let mut objects = Vec::with_capacity(file.objects.len());
    for (i, object) in file.objects.iter().enumerate() {
        let spec = cx.object(i, object, base, tick_dt_s, gravity_mm_per_s2)?;
        if objects.iter().any(|o: &ObjectSpec| o.name == spec.name) {
            return Err(cx.invalid(
                &object.name,
                &format!("objects[{i}].name"),
                "duplicate object name",
            ));
        }
        objects.push(spec);
    }
    let mut tools: Vec<ToolSpec> = Vec::with_capacity(file.tools.len());
    for (i, tool) in file.tools.iter().enumerate() {
        let spec = cx.tool(i, tool, base)?;
        if tools.iter().any(|t| t.name == spec.name) {
            return Err(cx.invalid(
                &tool.name,
                &format!("tools[{i}].name"),
                "duplicate tool name",
            ));
        }
        if tools.iter().any(|t| t.device_id == spec.device_id) {
            return Err(cx.invalid(
                &tool.device,
                &format!("tools[{i}].device"),
                "device already drives another tool",
            ));
        }
        tools.push(spec);
    }
    let mut ties = Vec::with_capacity(file.ties.len());
    for (i, tie) in file.ties.iter().enumerate() {
        ties.push(cx.tie(i, tie, &objects)?);
    }
    let exercise = match &file.exercise {
        Some(section) => Some(cx.exercise(section, &tools, &objects)?),
        None => None,
    };
    Ok(World {
        source: path.to_owned(),
        scene,
        tick_hz,
        publish_hz,
        pose_timeout_s,
        collision_margin_mm: margin,
        gravity_mm_per_s2,
        tissue_threads,
        ties,
        objects,
        tools,
        exercise,
    })
}

/// The most threads `[sim] threads` may ask for.
pub const MAX_TISSUE_THREADS: usize = 64;

/// What the machine can spare for the tissue passes when the world does not say: every core but two (one for
/// zenoh and the publisher, one for the device loops and whatever else shares the machine), at least one (the
/// tick's own thread: no workers), at most 8 (the pad's passes stop scaling well before that).
pub fn default_tissue_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_sub(2).clamp(1, 8)
}

/// The most targets an exercise may have.
pub const MAX_EXERCISE_TARGETS: usize = 64;

fn line_of(text: &str, byte: usize) -> usize {
    text.as_bytes()[..byte.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// A Gmsh mesh (a tetrahedral volume) rather than an OBJ surface: the `.msh` extension, any case.
fn is_msh_path(mesh: &str) -> bool {
    Path::new(mesh)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("msh"))
}

struct Context<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Context<'_> {
    fn line(&self, span: Range<usize>) -> usize {
        line_of(self.text, span.start)
    }

    fn invalid<T>(&self, at: &Spanned<T>, key: &str, message: impl Into<String>) -> WorldError {
        WorldError::Invalid {
            file: self.path.to_owned(),
            line: self.line(at.span()),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    fn check<T>(
        &self,
        at: &Spanned<T>,
        key: &str,
        ok: bool,
        message: &str,
    ) -> Result<(), WorldError> {
        if ok {
            Ok(())
        } else {
            Err(self.invalid(at, key, message))
        }
    }

    fn positive(&self, at: &Spanned<f32>, key: &str) -> Result<f32, WorldError> {
        let v = *at.get_ref();
        self.check(
            at,
            key,
            v.is_finite() && v > 0.0,
            &format!("must be a positive number (got {v})"),
        )?;
        Ok(v)
    }

    fn non_negative(&self, at: &Option<Spanned<f32>>, key: &str) -> Result<f32, WorldError> {
        let Some(at) = at else { return Ok(0.0) };
        let v = *at.get_ref();
        self.check(
            at,
            key,
            v.is_finite() && v >= 0.0,
            &format!("must be >= 0 (got {v})"),
        )?;
        Ok(v)
    }
}

//! Validating a parsed world file into a [`World`]. Each check names the file, the key and the line.

use std::ops::Range;
use std::path::{Path, PathBuf};

use thiserror::Error;
use toml::Spanned;

use super::exercise_spec::{ExerciseKind, ExerciseSpec, SampleSpec, TargetSpec};
use super::extrude::{MAX_EXTRUDE_LAYERS, extrude_surface};
use super::file_format::{
    ActivationName, ElasticModel, ExerciseSection, FixedSection, InstrumentKindName,
    InstrumentSection, IntegratorName, LawSection, MaterialSection, MaterialValue, ObjectSection,
    ShapeSection, TargetSection, TieSection, ToolSection, WorldFile,
};
use super::material_presets::material_presets;
use super::mesh_file::{MeshError, SurfaceMesh, load_obj_mesh, validate_closed};
use super::tet_mesh::load_msh_mesh;
use crate::tissue::{RegionParams, SpringLaw, TieSet, Vec3};

/// Why a world was refused. The server does not start with a world that fails here.
#[derive(Debug, Error)]
pub enum WorldError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Read {
        /// World file.
        file: PathBuf,
        /// The I/O error.
        message: String,
    },
    /// TOML syntax, an unknown key, a missing key or a wrong type.
    #[error("{file}:{line}: {message}")]
    Syntax {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// What the TOML parser reported (it names the key).
        message: String,
    },
    /// A value out of its domain.
    #[error("{file}:{line}: `{key}`: {message}")]
    Invalid {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// Dotted key, e.g. `objects[0].material.stiffness_n_per_mm`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A mesh file that is missing, unreadable or not a valid surface.
    #[error("{file}:{line}: `{key}` = {mesh:?}: {reason}")]
    Mesh {
        /// World file.
        file: PathBuf,
        /// 1-based line.
        line: usize,
        /// Dotted key of the mesh entry.
        key: String,
        /// Mesh path as written.
        mesh: String,
        /// What is wrong with it.
        reason: MeshError,
    },
}

/// A validated world: everything the server needs to build the scene.
#[derive(Debug, Clone)]
pub struct World {
    /// The file it came from.
    pub source: PathBuf,
    /// Scene name (key segment).
    pub scene: String,
    /// Sim tick rate, Hz.
    pub tick_hz: f64,
    /// Mesh-delta / tool-state publish rate, Hz.
    pub publish_hz: f64,
    /// A device with no pose for this long has its tool released, seconds.
    pub pose_timeout_s: f64,
    /// Broad-phase loosening around each tool, mm.
    pub collision_margin_mm: f32,
    /// Uniform acceleration of every free node, mm/s^2 (default none: the tissue's anchors hold it).
    pub gravity_mm_per_s2: [f32; 3],
    /// `[sim] threads`: threads the tissue passes spread over, the tick's own included (`None`: what the
    /// machine can spare, [`default_tissue_threads`]). Never changes a result, only the time.
    pub tissue_threads: Option<usize>,
    /// Tie-nodes between objects.
    pub ties: Vec<TieSet>,
    /// Deformable objects.
    pub objects: Vec<ObjectSpec>,
    /// Tools.
    pub tools: Vec<ToolSpec>,
    /// The training exercise (`[exercise]`), if the world is one.
    pub exercise: Option<ExerciseSpec>,
}

/// One deformable object.
#[derive(Debug, Clone)]
pub struct ObjectSpec {
    /// Name (key segment).
    pub name: String,
    /// Surface, mm. For a volume (a `.msh` file or an extrusion) its positions hold every node, surface nodes
    /// first; interior nodes are on no triangle.
    pub mesh: SurfaceMesh,
    /// Tetrahedra over the mesh's nodes, positively oriented (empty for a surface-only object).
    pub tets: Vec<[u32; 4]>,
    /// Time integrator.
    pub integrator: IntegratorName,
    /// Solver iterations per step (XPBD sweeps, CG iterations, relaxation sweeps); `None` = the method's default.
    pub solver_iterations: Option<u32>,
    /// Integration step, seconds (the tick is split into substeps of at most this).
    pub dt_s: f32,
    /// Quantization bounds are the rest bounding box grown by this, mm.
    pub quant_margin_mm: f32,
    /// A vertex is re-sent to viewers once they hold it further than this from its position, mm.
    pub delta_tolerance_mm: f32,
    /// Material.
    pub material: MaterialSpec,
    /// Fixed-node selections.
    pub fixed: Vec<FixedSelection>,
    /// Region of deformation (`None`: the whole object is integrated every tick).
    pub region: Option<RegionParams>,
    /// Ticks per step of the object (1: it steps every tick; `N > 1`: a multi-rate object, stepped every `N`
    /// ticks with `N` ticks' time, on its own thread: see [`crate::multirate`]).
    pub ticks_per_step: u32,
}

/// How node masses are given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MassSpec {
    /// Total mass, distributed by vertex area share (a volume: by tetrahedron volume share).
    TotalKg(f32),
    /// Density: for a sheet, times thickness, distributed by vertex area share; for a volume, by tetrahedron
    /// volume share.
    Density {
        /// kg/m^3.
        kg_per_m3: f32,
        /// Thickness of the sheet, mm (0 for a volume, whose mass comes from its tetrahedra).
        thickness_mm: f32,
    },
}

/// Mass-spring material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialSpec {
    /// Node masses.
    pub mass: MassSpec,
    /// Per-edge spring stiffness, N/mm.
    pub stiffness_n_per_mm: f32,
    /// Per-edge damping along the edge, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// Spring from each free node to its rest position (the underlying tissue), N/mm.
    pub anchor_stiffness_n_per_mm: f32,
    /// Viscous drag on every node, 1/s.
    pub drag_per_s: f32,
    /// Spring law.
    pub law: SpringLaw,
    /// Global volume preservation, N/mm^2 (0 = off; closed surfaces only).
    pub global_bulk_modulus_n_per_mm2: f32,
    /// Per-tetrahedron volume preservation, N/mm^2 (0 = off).
    pub tet_bulk_modulus_n_per_mm2: f32,
    /// The tissue tears where a spring is stretched past this strain (length / rest - 1); `None`: it never tears.
    pub tear_strain: Option<f32>,
    /// Drag a sharp edge feels against its motion while it cuts this tissue, N.
    pub cut_resistance_n: f32,
    /// Share of its rest length a spring loses when both its ends are fully burnt (0: burns do not shrink).
    pub burn_shrink: f32,
    /// Coulomb friction coefficient between a tool and this tissue (0: frictionless).
    pub friction_coefficient: f32,
    /// Corotational finite elements (`model = "fem-corotational"`); the springs then carry no stiffness.
    pub fem: Option<crate::tissue::fem::FemMaterial>,
    /// Springs calibrated from Young's modulus and Poisson's ratio (a mass-spring object given
    /// `youngs_modulus_kpa`); `stiffness_n_per_mm` is then unused.
    pub calibrated: Option<SpringCalibration>,
}

/// What calibrated springs are fitted to ([`crate::tissue::calibration`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringCalibration {
    /// Young's modulus, N/mm^2.
    pub youngs_modulus_n_per_mm2: f32,
    /// Poisson's ratio (a volume: at least 1/4; a sheet: 1/3).
    pub poisson_ratio: f32,
    /// A sheet's thickness, mm (0 for a volume).
    pub thickness_mm: f32,
}

impl MaterialSpec {
    /// Default of `cut_resistance_n`, N.
    pub const DEFAULT_CUT_RESISTANCE_N: f32 = 0.15;
}

/// A set of fixed nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FixedSelection {
    /// Nodes inside the box.
    Box {
        /// Lower corner, mm.
        min_mm: [f32; 3],
        /// Upper corner, mm.
        max_mm: [f32; 3],
    },
    /// Nodes on or beyond the plane (signed distance along `normal` >= -tolerance).
    Plane {
        /// A point of the plane, mm.
        point_mm: [f32; 3],
        /// Unit normal pointing to the selected side.
        normal: [f32; 3],
        /// Tolerance, mm.
        tolerance_mm: f32,
    },
}

impl FixedSelection {
    /// Whether the selection contains `p`.
    pub fn contains(&self, p: [f32; 3]) -> bool {
        match self {
            FixedSelection::Box { min_mm, max_mm } => {
                (0..3).all(|a| p[a] >= min_mm[a] && p[a] <= max_mm[a])
            }
            FixedSelection::Plane {
                point_mm,
                normal,
                tolerance_mm,
            } => {
                (0..3)
                    .map(|a| (p[a] - point_mm[a]) * normal[a])
                    .sum::<f32>()
                    >= -tolerance_mm
            }
        }
    }
}

/// A tool's collision shape, mm.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolShapeSpec {
    /// Ball.
    Sphere {
        /// Radius, mm.
        radius_mm: f32,
    },
    /// Capsule along the tool's local z.
    Capsule {
        /// Half segment length, mm.
        half_length_mm: f32,
        /// Radius, mm.
        radius_mm: f32,
    },
    /// A closed, rigid triangle mesh in the tool frame.
    Mesh(SurfaceMesh),
}

/// A tool and the device that drives it.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name.
    pub name: String,
    /// Device id bound to it (key segment).
    pub device_id: String,
    /// Collision shape.
    pub shape: ToolShapeSpec,
    /// Where the device frame's origin sits in the world, mm (device axes are world axes).
    pub device_origin_in_world_mm: [f32; 3],
    /// Largest force the server will ever send for this tool, N (the device's own maximum also applies).
    pub max_force_n: f32,
    /// How the tool follows its device pose (`coupling = { ... }`).
    pub coupling: crate::haptics::CouplingParams,
    /// What the tool does beyond pushing (`instrument = { kind = ... }`; default a probe).
    pub instrument: crate::world::InstrumentSpec,
    /// The instrument's shaft (`shaft = { radius_mm, length_mm }`), which pushes tissue as the tip does.
    pub shaft: Option<ShaftSpec>,
}

/// An instrument's shaft: a capsule from the tool origin `length_mm` up the tool's local +z (toward the hand),
/// `radius_mm` thick. It is blunt: it pushes the tissue it touches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShaftSpec {
    /// Radius, mm.
    pub radius_mm: f32,
    /// Length from the tool origin, mm.
    pub length_mm: f32,
}

/// Read, parse and validate a world file (mesh paths are relative to it).
pub fn load_world(path: &Path) -> Result<World, WorldError> {
    let text = std::fs::read_to_string(path).map_err(|e| WorldError::Read {
        file: path.to_owned(),
        message: e.to_string(),
    })?;
    parse_world(path, &text)
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

    fn object(
        &self,
        i: usize,
        object: &ObjectSection,
        base: &Path,
        tick_dt_s: f32,
        gravity_mm_per_s2: [f32; 3],
    ) -> Result<ObjectSpec, WorldError> {
        let key = |k: &str| format!("objects[{i}].{k}");
        let name = object.name.get_ref().clone();
        if let Err(e) = sinew_protocol::keys::validate_segment("object", &name) {
            return Err(self.invalid(&object.name, &key("name"), e.to_string()));
        }
        let ticks_per_step = self.ticks_per_step(i, object, tick_dt_s)?;
        let step_dt_s = tick_dt_s * ticks_per_step as f32;
        let dt_s = self.positive(&object.dt_s, &key("dt_s"))?;
        let period = if ticks_per_step > 1 {
            "the object's step period (1 / step_hz)"
        } else {
            "the tick period"
        };
        self.check(
            &object.dt_s,
            &key("dt_s"),
            dt_s <= step_dt_s * (1.0 + 1e-6) && dt_s >= step_dt_s / MAX_SUBSTEPS,
            &format!(
                "must be within {period} {step_dt_s} s and at least 1/{MAX_SUBSTEPS} of it \
                 (at most {MAX_SUBSTEPS} substeps a step)"
            ),
        )?;
        let quant_margin_mm = self.positive(&object.quant_margin_mm, &key("quant_margin_mm"))?;
        let delta_tolerance_mm = *object.delta_tolerance_mm.get_ref();
        self.check(
            &object.delta_tolerance_mm,
            &key("delta_tolerance_mm"),
            delta_tolerance_mm.is_finite() && (0.0..=1.0).contains(&delta_tolerance_mm),
            &format!("must be in [0, 1] mm (got {delta_tolerance_mm})"),
        )?;
        let is_volume = object.extrude.is_some() || is_msh_path(object.mesh.get_ref());
        let model = object
            .model
            .as_ref()
            .map_or(ElasticModel::MassSpring, |m| *m.get_ref());
        if let Some(at) = &object.model
            && model == ElasticModel::FemCorotational
        {
            if !is_volume {
                return Err(self.invalid(
                    at,
                    &key("model"),
                    "fem-corotational needs tetrahedra: load a .msh mesh or add `extrude` to this OBJ",
                ));
            }
            if *object.integrator.get_ref() == IntegratorName::Xpbd {
                return Err(self.invalid(
                    &object.integrator,
                    &key("integrator"),
                    "xpbd constrains springs and volumes; fem-corotational needs a force-based integrator (implicit-euler is the one for tissue stiffness)",
                ));
            }
        }
        let material_keys = self.resolved_material(i, &object.material, is_volume)?;
        let material = self.material(i, &material_keys, is_volume, model, &object.name)?;
        let mut fixed = Vec::with_capacity(object.fixed.len());
        for (f, selection) in object.fixed.iter().enumerate() {
            fixed.push(self.fixed(&key(&format!("fixed[{f}]")), selection)?);
        }
        let (mut mesh, tets) = self.object_mesh(i, object, base)?;
        if let Some(at) = &object.offset_mm {
            let offset = *at.get_ref();
            self.check(
                at,
                &key("offset_mm"),
                offset.iter().all(|c| c.is_finite() && c.abs() <= 1e6),
                "must be finite and within a kilometre",
            )?;
            for p in &mut mesh.positions_mm {
                for k in 0..3 {
                    p[k] += offset[k];
                }
            }
        }
        if let Some(at) = &material_keys.tet_bulk_modulus_kpa
            && material.tet_bulk_modulus_n_per_mm2 > 0.0
            && tets.is_empty()
        {
            return Err(self.invalid(
                at,
                &key("material.tet_bulk_modulus_kpa"),
                "per-tetrahedron volume needs tetrahedra: load a .msh mesh or add `extrude` to this OBJ",
            ));
        }
        let integrator = *object.integrator.get_ref();
        let solver_iterations = match &object.solver_iterations {
            None => None,
            Some(at) => {
                let n = *at.get_ref();
                self.check(
                    at,
                    &key("solver_iterations"),
                    (1..=1000).contains(&n),
                    "must be in 1..=1000",
                )?;
                if matches!(
                    integrator,
                    IntegratorName::ExplicitEuler
                        | IntegratorName::SymplecticEuler
                        | IntegratorName::Rk2
                        | IntegratorName::Rk4
                ) {
                    return Err(self.invalid(
                        at,
                        &key("solver_iterations"),
                        format!("{} takes no iterations (only quasi-static, implicit-euler and xpbd do)", integrator.as_str()),
                    ));
                }
                Some(n)
            }
        };
        if material.global_bulk_modulus_n_per_mm2 > 0.0
            && let Err(reason) = validate_closed(&mesh)
        {
            return Err(WorldError::Mesh {
                file: self.path.to_owned(),
                line: self.line(object.mesh.span()),
                key: key("material.bulk_modulus_kpa"),
                mesh: object.mesh.get_ref().clone(),
                reason,
            });
        }
        let region = self.region(i, object, &material, gravity_mm_per_s2)?;
        self.multirate_combinations(i, object, &material, ticks_per_step)?;
        let spec = ObjectSpec {
            name,
            mesh,
            tets,
            integrator,
            solver_iterations,
            dt_s,
            quant_margin_mm,
            delta_tolerance_mm,
            material,
            fixed,
            region,
            ticks_per_step,
        };
        // An explicit integrator must be stable at this dt for this stiffness, damping and mass.
        let model = crate::tissue::MassSpringModel::build(&spec, Vec3::from(gravity_mm_per_s2));
        if let Some(stable_dt_s) = crate::tissue::stability::max_stable_dt_s(integrator, &model)
            && dt_s > stable_dt_s
        {
            let undamped = material.drag_per_s == 0.0
                && material.damping_n_s_per_mm == 0.0
                && matches!(
                    integrator,
                    IntegratorName::ExplicitEuler | IntegratorName::Rk2
                );
            let hint = if undamped {
                "it is unstable at every step without damping: add damping or drag, or choose symplectic-euler".to_owned()
            } else {
                format!(
                    "its stability bound is {stable_dt_s:.6} s: lower dt_s, raise mass, or choose an implicit method"
                )
            };
            return Err(self.invalid(
                &object.dt_s,
                &key("dt_s"),
                format!(
                    "{dt_s} s is too large for {} with this stiffness, damping and mass: {hint}",
                    integrator.as_str()
                ),
            ));
        }
        if model.free_node_count() == 0 {
            return Err(self.invalid(
                &object.name,
                &key("fixed"),
                "every node is fixed: nothing can deform",
            ));
        }
        Ok(spec)
    }

    /// The object's mesh and tetrahedra: an OBJ surface (no tetrahedra), an OBJ surface extruded into a
    /// volume (`extrude`), or a Gmsh `.msh` volume.
    fn object_mesh(
        &self,
        i: usize,
        object: &ObjectSection,
        base: &Path,
    ) -> Result<(SurfaceMesh, Vec<[u32; 4]>), WorldError> {
        let key = |k: &str| format!("objects[{i}].{k}");
        let mesh_error = |key: String, line: usize| {
            move |reason| WorldError::Mesh {
                file: self.path.to_owned(),
                line,
                key,
                mesh: object.mesh.get_ref().clone(),
                reason,
            }
        };
        let mesh_line = self.line(object.mesh.span());
        let path = base.join(object.mesh.get_ref());
        let scale_to_mm = object.units.to_mm();
        if is_msh_path(object.mesh.get_ref()) {
            if let Some(extrude) = &object.extrude {
                return Err(self.invalid(
                    extrude,
                    &key("extrude"),
                    "a .msh mesh is already a volume: remove `extrude` (it extrudes OBJ surfaces)",
                ));
            }
            let volume =
                load_msh_mesh(&path, scale_to_mm).map_err(mesh_error(key("mesh"), mesh_line))?;
            return Ok((volume.surface, volume.tets));
        }
        let surface =
            load_obj_mesh(&path, scale_to_mm).map_err(mesh_error(key("mesh"), mesh_line))?;
        let Some(extrude) = &object.extrude else {
            return Ok((surface, Vec::new()));
        };
        let section = extrude.get_ref();
        let thickness_mm = self.positive(&section.thickness_mm, &key("extrude.thickness_mm"))?;
        let layers = *section.layers.get_ref();
        self.check(
            &section.layers,
            &key("extrude.layers"),
            (1..=i64::from(MAX_EXTRUDE_LAYERS)).contains(&layers),
            &format!("must be in 1..={MAX_EXTRUDE_LAYERS} (got {layers})"),
        )?;
        let volume = extrude_surface(&surface, thickness_mm, layers as u32)
            .map_err(mesh_error(key("extrude"), self.line(extrude.span())))?;
        Ok((volume.surface, volume.tets))
    }

    /// `is_volume`: the object has tetrahedra (a `.msh` mesh or `extrude`), so density needs no thickness.
    /// The object's material keys, with a preset's modulus, ratio and density filled in where they are not given
    /// (errors in those then name the preset's line).
    fn resolved_material(
        &self,
        i: usize,
        at: &Spanned<MaterialValue>,
        is_volume: bool,
    ) -> Result<MaterialSection, WorldError> {
        let (mut keys, preset) = match at.get_ref() {
            MaterialValue::Table(m) => ((**m).clone(), m.preset.clone()),
            MaterialValue::Preset(name) => (
                MaterialSection::default(),
                Some(Spanned::new(at.span(), name.clone())),
            ),
        };
        let Some(preset) = preset else {
            return Ok(keys);
        };
        let key = format!("objects[{i}].material.preset");
        let presets = material_presets().map_err(|e| self.invalid(&preset, &key, e))?;
        let Some(values) = presets.get(preset.get_ref()) else {
            let known: Vec<&str> = presets.keys().map(String::as_str).collect();
            return Err(self.invalid(
                &preset,
                &key,
                format!(
                    "unknown material preset `{}`: the presets are {}",
                    preset.get_ref(),
                    known.join(", ")
                ),
            ));
        };
        if !is_volume {
            return Err(self.invalid(
                &preset,
                &key,
                "material presets describe bulk tissue: use them on a volume (a .msh mesh, or `extrude`), or give a sheet's stiffness_n_per_mm",
            ));
        }
        let here = |v: f32| Spanned::new(preset.span(), v);
        keys.youngs_modulus_kpa
            .get_or_insert_with(|| here(values.youngs_modulus_kpa));
        keys.poisson_ratio
            .get_or_insert_with(|| here(values.poisson_ratio));
        if keys.mass_kg.is_none() {
            keys.density_kg_per_m3
                .get_or_insert_with(|| here(values.density_kg_per_m3));
        }
        Ok(keys)
    }

    /// `model` says what carries the elasticity; `object` is blamed for a key that is missing.
    fn material(
        &self,
        i: usize,
        m: &MaterialSection,
        is_volume: bool,
        model: ElasticModel,
        object: &Spanned<String>,
    ) -> Result<MaterialSpec, WorldError> {
        let key = |k: &str| format!("objects[{i}].material.{k}");
        let mass = match (&m.mass_kg, &m.density_kg_per_m3, &m.thickness_mm) {
            (_, _, Some(thickness)) if is_volume => {
                return Err(self.invalid(
                    thickness,
                    &key("thickness_mm"),
                    "a volume mesh (.msh or extrude) takes its mass from its tetrahedra: give density_kg_per_m3 alone",
                ));
            }
            (None, Some(density), None) if is_volume => MassSpec::Density {
                kg_per_m3: self.positive(density, &key("density_kg_per_m3"))?,
                thickness_mm: 0.0,
            },
            (Some(total), None, None) => MassSpec::TotalKg(self.positive(total, &key("mass_kg"))?),
            // A calibrated sheet's thickness sets its stiffness, not its mass.
            (Some(total), None, Some(_))
                if model == ElasticModel::MassSpring && m.youngs_modulus_kpa.is_some() =>
            {
                MassSpec::TotalKg(self.positive(total, &key("mass_kg"))?)
            }
            (None, Some(density), Some(thickness)) => MassSpec::Density {
                kg_per_m3: self.positive(density, &key("density_kg_per_m3"))?,
                thickness_mm: self.positive(thickness, &key("thickness_mm"))?,
            },
            _ => {
                return Err(self.invalid(
                    object,
                    &key("mass_kg"),
                    if is_volume {
                        "give either mass_kg or density_kg_per_m3"
                    } else {
                        "give either mass_kg, or density_kg_per_m3 with thickness_mm"
                    },
                ));
            }
        };
        let elastic = self.elastic(i, m)?;
        let mut calibrated = None;
        let (stiffness, fem) = match (model, &m.stiffness_n_per_mm, elastic) {
            (ElasticModel::FemCorotational, Some(at), _) => {
                return Err(self.invalid(
                    at,
                    &key("stiffness_n_per_mm"),
                    "fem-corotational takes its stiffness from youngs_modulus_kpa and poisson_ratio: remove stiffness_n_per_mm",
                ));
            }
            (ElasticModel::FemCorotational, None, Some((youngs, poisson))) => (
                0.0,
                Some(crate::tissue::fem::FemMaterial {
                    youngs_modulus_n_per_mm2: youngs * N_PER_MM2_PER_KPA,
                    poisson_ratio: poisson,
                    corotated: true,
                }),
            ),
            (ElasticModel::FemCorotational, None, None) => {
                return Err(self.invalid(
                    object,
                    &key("youngs_modulus_kpa"),
                    "fem-corotational needs youngs_modulus_kpa and poisson_ratio in [objects.material]",
                ));
            }
            (ElasticModel::MassSpring, Some(at), None) => {
                (self.positive(at, &key("stiffness_n_per_mm"))?, None)
            }
            (ElasticModel::MassSpring, Some(at), Some(_)) => {
                return Err(self.invalid(
                    at,
                    &key("stiffness_n_per_mm"),
                    "give stiffness_n_per_mm, or youngs_modulus_kpa with poisson_ratio, not both",
                ));
            }
            (ElasticModel::MassSpring, None, Some((youngs, poisson))) => {
                calibrated = Some(self.spring_calibration(i, m, is_volume, youngs, poisson)?);
                (0.0, None)
            }
            (ElasticModel::MassSpring, None, None) => {
                return Err(self.invalid(
                    object,
                    &key("stiffness_n_per_mm"),
                    "give stiffness_n_per_mm (N/mm per edge), or youngs_modulus_kpa with poisson_ratio",
                ));
            }
        };
        let damping = match &m.damping_n_s_per_mm {
            None => 0.0,
            Some(at) => {
                let damping = *at.get_ref();
                self.check(
                    at,
                    &key("damping_n_s_per_mm"),
                    damping.is_finite() && damping >= 0.0,
                    &format!("must be >= 0 (got {damping})"),
                )?;
                damping
            }
        };
        let law = match &m.law {
            None => SpringLaw::Linear,
            Some(at) => match at.get_ref() {
                LawSection::Linear => SpringLaw::Linear,
                LawSection::PiecewiseLinear {
                    knee_strain,
                    stiffness_ratio,
                } => {
                    self.check(
                        at,
                        &key("law"),
                        knee_strain.is_finite()
                            && *knee_strain > 0.0
                            && stiffness_ratio.is_finite()
                            && *stiffness_ratio > 0.0
                            && *stiffness_ratio <= 1000.0,
                        "piecewise-linear needs knee_strain > 0 and stiffness_ratio in (0, 1000]",
                    )?;
                    SpringLaw::PiecewiseLinear {
                        knee_strain: *knee_strain,
                        stiffness_ratio: *stiffness_ratio,
                    }
                }
                LawSection::Exponential { stiffening } => {
                    self.check(
                        at,
                        &key("law"),
                        stiffening.is_finite() && *stiffening > 0.0 && *stiffening <= 100.0,
                        "exponential needs stiffening in (0, 100]",
                    )?;
                    SpringLaw::Exponential {
                        stiffening: *stiffening,
                    }
                }
            },
        };
        Ok(MaterialSpec {
            fem,
            calibrated,
            law,
            global_bulk_modulus_n_per_mm2: self
                .non_negative(&m.bulk_modulus_kpa, &key("bulk_modulus_kpa"))?
                * N_PER_MM2_PER_KPA,
            tet_bulk_modulus_n_per_mm2: self
                .non_negative(&m.tet_bulk_modulus_kpa, &key("tet_bulk_modulus_kpa"))?
                * N_PER_MM2_PER_KPA,
            mass,
            stiffness_n_per_mm: stiffness,
            damping_n_s_per_mm: damping,
            anchor_stiffness_n_per_mm: self.non_negative(
                &m.anchor_stiffness_n_per_mm,
                &key("anchor_stiffness_n_per_mm"),
            )?,
            drag_per_s: self.non_negative(&m.drag_per_s, &key("drag_per_s"))?,
            tear_strain: match &m.tear_strain {
                None => None,
                Some(at) => {
                    let strain = *at.get_ref();
                    self.check(
                        at,
                        &key("tear_strain"),
                        strain.is_finite() && strain > 0.0 && strain <= 100.0,
                        "must be a strain above 0 and at most 100 (0.5 tears a spring stretched to 1.5 times its rest length)",
                    )?;
                    Some(strain)
                }
            },
            cut_resistance_n: self.optional_in(
                &m.cut_resistance_n,
                &key("cut_resistance_n"),
                0.0..=5.0,
                MaterialSpec::DEFAULT_CUT_RESISTANCE_N,
                "must be 0 to 5 N",
            )?,
            burn_shrink: self.optional_in(
                &m.burn_shrink,
                &key("burn_shrink"),
                0.0..=0.5,
                0.0,
                "must be 0 to 0.5 (the share of rest length a fully burnt spring loses)",
            )?,
            friction_coefficient: self.optional_in(
                &m.friction_coefficient,
                &key("friction_coefficient"),
                0.0..=2.0,
                0.0,
                "must be 0 to 2 (Coulomb's coefficient; 0 is frictionless)",
            )?,
        })
    }

    /// What a mass-spring object's springs are calibrated to: a volume's Poisson's ratio must be at least the
    /// network's 1/4 (a volume term adds the rest), a sheet's must be its network's 1/3 and it needs a thickness.
    fn spring_calibration(
        &self,
        i: usize,
        m: &MaterialSection,
        is_volume: bool,
        youngs_kpa: f32,
        poisson: f32,
    ) -> Result<SpringCalibration, WorldError> {
        use crate::tissue::calibration::{SHEET_NETWORK_POISSON, TET_NETWORK_POISSON};
        let key = |k: &str| format!("objects[{i}].material.{k}");
        // Both are given (the caller has checked them in pairs).
        let (Some(at_youngs), Some(at_poisson)) = (&m.youngs_modulus_kpa, &m.poisson_ratio) else {
            return Ok(SpringCalibration {
                youngs_modulus_n_per_mm2: youngs_kpa * N_PER_MM2_PER_KPA,
                poisson_ratio: poisson,
                thickness_mm: 0.0,
            });
        };
        let thickness_mm = if is_volume {
            if poisson < TET_NETWORK_POISSON {
                return Err(self.invalid(
                    at_poisson,
                    &key("poisson_ratio"),
                    format!("calibrated springs on a volume need poisson_ratio >= {TET_NETWORK_POISSON} (a spring network's own ratio; a volume term adds the rest): use model = \"fem-corotational\" for {poisson}"),
                ));
            }
            0.0
        } else {
            if (poisson - SHEET_NETWORK_POISSON).abs() > 0.005 {
                return Err(self.invalid(
                    at_poisson,
                    &key("poisson_ratio"),
                    format!("a sheet of springs has Poisson's ratio 1/3 whatever its constants (got {poisson}): give poisson_ratio = 0.333, or make the tissue a volume (extrude or .msh)"),
                ));
            }
            match &m.thickness_mm {
                Some(at) => self.positive(at, &key("thickness_mm"))?,
                None => {
                    return Err(self.invalid(
                        at_youngs,
                        &key("thickness_mm"),
                        "calibrated springs on a sheet need thickness_mm, the sheet's thickness (its stiffness is E times thickness)",
                    ));
                }
            }
        };
        Ok(SpringCalibration {
            youngs_modulus_n_per_mm2: youngs_kpa * N_PER_MM2_PER_KPA,
            poisson_ratio: poisson,
            thickness_mm,
        })
    }

    /// Young's modulus (kPa) and Poisson's ratio, if given: both or neither, each in range.
    fn elastic(&self, i: usize, m: &MaterialSection) -> Result<Option<(f32, f32)>, WorldError> {
        let key = |k: &str| format!("objects[{i}].material.{k}");
        match (&m.youngs_modulus_kpa, &m.poisson_ratio) {
            (None, None) => Ok(None),
            (Some(at), None) => Err(self.invalid(
                at,
                &key("poisson_ratio"),
                "youngs_modulus_kpa needs poisson_ratio beside it",
            )),
            (None, Some(at)) => Err(self.invalid(
                at,
                &key("youngs_modulus_kpa"),
                "poisson_ratio needs youngs_modulus_kpa beside it",
            )),
            (Some(e), Some(nu)) => {
                let youngs = *e.get_ref();
                self.check(
                    e,
                    &key("youngs_modulus_kpa"),
                    youngs.is_finite() && youngs > 0.0 && youngs <= MAX_YOUNGS_MODULUS_KPA,
                    &format!("must be above 0 and at most {MAX_YOUNGS_MODULUS_KPA} kPa (got {youngs}); soft tissue is 0.1 to 1000 kPa"),
                )?;
                let poisson = *nu.get_ref();
                self.check(
                    nu,
                    &key("poisson_ratio"),
                    poisson.is_finite() && (0.0..=MAX_POISSON_RATIO).contains(&poisson),
                    &format!("must be 0 to {MAX_POISSON_RATIO} (got {poisson}); 0.5 is incompressible, which no finite stiffness holds"),
                )?;
                Ok(Some((youngs, poisson)))
            }
        }
    }

    fn fixed(
        &self,
        key: &str,
        selection: &Spanned<FixedSection>,
    ) -> Result<FixedSelection, WorldError> {
        let finite = |v: &[f32]| v.iter().all(|c| c.is_finite());
        match selection.get_ref() {
            FixedSection::Box { min_mm, max_mm } => {
                let ok = finite(min_mm) && finite(max_mm) && (0..3).all(|a| min_mm[a] <= max_mm[a]);
                self.check(
                    selection,
                    key,
                    ok,
                    "box needs finite min_mm <= max_mm on every axis",
                )?;
                Ok(FixedSelection::Box {
                    min_mm: *min_mm,
                    max_mm: *max_mm,
                })
            }
            FixedSection::Plane {
                point_mm,
                normal,
                tolerance_mm,
            } => {
                let len = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
                let ok = finite(point_mm)
                    && finite(normal)
                    && len > 1e-6
                    && tolerance_mm.is_finite()
                    && *tolerance_mm >= 0.0;
                self.check(
                    selection,
                    key,
                    ok,
                    "plane needs a finite point_mm, a non-zero normal and tolerance_mm >= 0",
                )?;
                Ok(FixedSelection::Plane {
                    point_mm: *point_mm,
                    normal: normal.map(|c| c / len),
                    tolerance_mm: *tolerance_mm,
                })
            }
        }
    }

    fn tie(
        &self,
        i: usize,
        tie: &Spanned<TieSection>,
        objects: &[ObjectSpec],
    ) -> Result<TieSet, WorldError> {
        let key = format!("ties[{i}]");
        let t = tie.get_ref();
        let find = |name: &str| objects.iter().position(|o| o.name == name);
        let (Some(a), Some(b)) = (find(&t.objects[0]), find(&t.objects[1])) else {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "names an unknown object (known: {})",
                    objects
                        .iter()
                        .map(|o| o.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        };
        self.check(
            tie,
            &format!("{key}.objects"),
            a != b,
            "ties link two different objects",
        )?;
        if let Some(o) = [a, b].into_iter().find(|&o| objects[o].ticks_per_step > 1) {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "`{}` steps at its own rate (`step_hz`): ties couple two objects every substep; drop one of them",
                    objects[o].name
                ),
            ));
        }
        if let Some(o) = [a, b].into_iter().find(|&o| objects[o].region.is_some()) {
            return Err(self.invalid(
                tie,
                &format!("{key}.objects"),
                format!(
                    "`{}` is region-tracked (`region`): a tied object moves where the tie pulls it, not only where a tool touches; drop one of them",
                    objects[o].name
                ),
            ));
        }
        self.check(
            tie,
            &format!("{key}.within_mm"),
            t.within_mm.is_finite() && t.within_mm > 0.0,
            "must be positive",
        )?;
        self.check(
            tie,
            &format!("{key}.stiffness_n_per_mm"),
            t.stiffness_n_per_mm.is_finite() && t.stiffness_n_per_mm > 0.0,
            "must be positive",
        )?;
        self.check(
            tie,
            &format!("{key}.damping_n_s_per_mm"),
            t.damping_n_s_per_mm.is_finite() && t.damping_n_s_per_mm >= 0.0,
            "must be >= 0",
        )?;
        let to_vec = |p: [f32; 3]| Vec3::new(p[0], p[1], p[2]);
        let nodes_b = &objects[b].mesh.positions_mm;
        let mut pairs = Vec::new();
        for (na, pa) in objects[a].mesh.positions_mm.iter().enumerate() {
            let pa = to_vec(*pa);
            let nearest = nodes_b
                .iter()
                .enumerate()
                .map(|(nb, pb)| (nb, (to_vec(*pb) - pa).norm()))
                .min_by(|x, y| x.1.total_cmp(&y.1));
            if let Some((nb, distance)) = nearest
                && distance <= t.within_mm
            {
                pairs.push((na as u32, nb as u32, to_vec(nodes_b[nb]) - pa));
            }
        }
        if pairs.is_empty() {
            return Err(self.invalid(
                tie,
                &format!("{key}.within_mm"),
                format!(
                    "no node of `{}` lies within {} mm of `{}`",
                    t.objects[0], t.within_mm, t.objects[1]
                ),
            ));
        }
        Ok(TieSet {
            object_a: a,
            object_b: b,
            pairs,
            stiffness_n_per_mm: t.stiffness_n_per_mm,
            damping_n_s_per_mm: t.damping_n_s_per_mm,
        })
    }

    fn exercise(
        &self,
        section: &Spanned<ExerciseSection>,
        tools: &[ToolSpec],
        objects: &[ObjectSpec],
    ) -> Result<ExerciseSpec, WorldError> {
        let e = section.get_ref();
        let name = e.name.get_ref().clone();
        self.check(&e.name, "exercise.name", !name.trim().is_empty(), "empty")?;
        let limit = *e.time_limit_s.get_ref();
        self.check(
            &e.time_limit_s,
            "exercise.time_limit_s",
            limit.is_finite() && limit > 0.0 && limit <= 86_400.0,
            &format!("must be a time in (0, 86400] s (got {limit})"),
        )?;
        let depth_limit_mm = match &e.depth_limit_mm {
            Some(at) => Some(self.positive(at, "exercise.depth_limit_mm")?),
            None => None,
        };
        if e.kind == ExerciseKind::AccurateTouch && depth_limit_mm.is_none() {
            return Err(self.invalid(
                section,
                "exercise.depth_limit_mm",
                "an accurate-touch exercise needs a depth limit",
            ));
        }
        let samples = self.exercise_samples(section, objects)?;
        let ranking = e.kind == ExerciseKind::StiffnessRanking;
        let list: &[Spanned<TargetSection>] = match &e.targets {
            Some(at) if ranking => {
                return Err(self.invalid(
                    at,
                    "exercise.targets",
                    "a stiffness-ranking exercise has samples, not targets",
                ));
            }
            Some(at) => {
                let list = at.get_ref();
                self.check(
                    at,
                    "exercise.targets",
                    !list.is_empty() && list.len() <= MAX_EXERCISE_TARGETS,
                    &format!(
                        "needs 1 to {MAX_EXERCISE_TARGETS} targets (got {})",
                        list.len()
                    ),
                )?;
                list
            }
            None if ranking => &[],
            None => {
                return Err(self.invalid(
                    section,
                    "exercise.targets",
                    "missing: list the targets as [[exercise.targets]] tables",
                ));
            }
        };
        let mut targets = Vec::with_capacity(list.len());
        for (i, target) in list.iter().enumerate() {
            let key = |k: &str| format!("exercise.targets[{i}].{k}");
            let t = target.get_ref();
            self.check(
                target,
                &key("at_mm"),
                t.at_mm.iter().all(|c| c.is_finite()),
                "must be finite",
            )?;
            self.check(
                target,
                &key("radius_mm"),
                t.radius_mm.is_finite() && t.radius_mm > 0.0,
                &format!("must be a positive number (got {})", t.radius_mm),
            )?;
            let tool = match &t.tool {
                Some(name) => {
                    Some(tools.iter().position(|s| &s.name == name).ok_or_else(|| {
                        self.invalid(
                            target,
                            &key("tool"),
                            format!(
                                "no tool named `{name}` (tools: {})",
                                tools
                                    .iter()
                                    .map(|s| s.name.as_str())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            ),
                        )
                    })?)
                }
                None if e.kind == ExerciseKind::Coordination => {
                    return Err(self.invalid(
                        target,
                        &key("tool"),
                        "a coordination target names the tool that must touch it",
                    ));
                }
                None => None,
            };
            targets.push(TargetSpec {
                at_mm: t.at_mm,
                radius_mm: t.radius_mm,
                tool,
            });
        }
        Ok(ExerciseSpec {
            name,
            kind: e.kind,
            time_limit_s: limit,
            depth_limit_mm,
            targets,
            samples,
        })
    }

    /// A ranking exercise's samples: at least two distinct objects of the world (none for other kinds).
    fn exercise_samples(
        &self,
        section: &Spanned<ExerciseSection>,
        objects: &[ObjectSpec],
    ) -> Result<Vec<SampleSpec>, WorldError> {
        let e = section.get_ref();
        let ranking = e.kind == ExerciseKind::StiffnessRanking;
        let Some(at) = &e.samples else {
            if ranking {
                return Err(self.invalid(
                    section,
                    "exercise.samples",
                    "missing: name the objects to rank, e.g. samples = [\"a\", \"b\"]",
                ));
            }
            return Ok(Vec::new());
        };
        self.check(
            at,
            "exercise.samples",
            ranking,
            "only a stiffness-ranking exercise has samples",
        )?;
        let names = at.get_ref();
        self.check(
            at,
            "exercise.samples",
            names.len() >= 2 && names.len() <= MAX_EXERCISE_TARGETS,
            &format!(
                "needs 2 to {MAX_EXERCISE_TARGETS} samples (got {})",
                names.len()
            ),
        )?;
        let mut samples: Vec<SampleSpec> = Vec::with_capacity(names.len());
        for name in names {
            let Some(object) = objects.iter().position(|o| &o.name == name) else {
                return Err(self.invalid(
                    at,
                    "exercise.samples",
                    format!(
                        "no object named `{name}` (objects: {})",
                        objects
                            .iter()
                            .map(|o| o.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            };
            if samples.iter().any(|s| s.object == object) {
                return Err(self.invalid(
                    at,
                    "exercise.samples",
                    format!("`{name}` is named twice"),
                ));
            }
            let spec = &objects[object];
            let mut min = [f32::MAX; 2];
            let mut max = [f32::MIN; 2];
            for p in &spec.mesh.positions_mm {
                for k in 0..2 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
            samples.push(SampleSpec {
                object,
                name: name.clone(),
                stiffness_n_per_mm: spec.material.stiffness_n_per_mm,
                min_xy_mm: min,
                max_xy_mm: max,
            });
        }
        Ok(samples)
    }

    fn tool(&self, i: usize, tool: &ToolSection, base: &Path) -> Result<ToolSpec, WorldError> {
        let key = |k: &str| format!("tools[{i}].{k}");
        let device_id = tool.device.get_ref().clone();
        if let Err(e) = sinew_protocol::keys::validate_segment("device", &device_id) {
            return Err(self.invalid(&tool.device, &key("device"), e.to_string()));
        }
        if tool.name.get_ref().is_empty() {
            return Err(self.invalid(&tool.name, &key("name"), "empty"));
        }
        let dims_ok = |dims: &[f32]| dims.iter().all(|d| d.is_finite() && *d > 0.0);
        let shape = match tool.shape.get_ref() {
            ShapeSection::Sphere { radius_mm } => {
                self.check(
                    &tool.shape,
                    &key("shape"),
                    dims_ok(&[*radius_mm]),
                    "radius_mm must be positive",
                )?;
                ToolShapeSpec::Sphere {
                    radius_mm: *radius_mm,
                }
            }
            ShapeSection::Capsule {
                half_length_mm,
                radius_mm,
            } => {
                self.check(
                    &tool.shape,
                    &key("shape"),
                    dims_ok(&[*half_length_mm, *radius_mm]),
                    "half_length_mm and radius_mm must be positive",
                )?;
                ToolShapeSpec::Capsule {
                    half_length_mm: *half_length_mm,
                    radius_mm: *radius_mm,
                }
            }
            ShapeSection::Mesh { mesh, units } => {
                let mesh_error = |reason| WorldError::Mesh {
                    file: self.path.to_owned(),
                    line: self.line(tool.shape.span()),
                    key: key("shape.mesh"),
                    mesh: mesh.clone(),
                    reason,
                };
                let surface = load_obj_mesh(&base.join(mesh), units.to_mm()).map_err(mesh_error)?;
                validate_closed(&surface).map_err(mesh_error)?;
                ToolShapeSpec::Mesh(surface)
            }
        };
        self.check(
            &tool.device,
            &key("device_origin_in_world_mm"),
            tool.device_origin_in_world_mm.iter().all(|c| c.is_finite()),
            "must be finite",
        )?;
        let max_force_n = self.positive(&tool.max_force_n, &key("max_force_n"))?;
        let mut coupling = crate::haptics::CouplingParams::default();
        if let Some(at) = &tool.coupling {
            let section = at.get_ref();
            let fields = [
                (
                    section.stiffness_n_per_mm,
                    "stiffness_n_per_mm",
                    &mut coupling.stiffness_n_per_mm,
                ),
                (
                    section.damping_n_s_per_mm,
                    "damping_n_s_per_mm",
                    &mut coupling.damping_n_s_per_mm,
                ),
                (
                    section.max_speed_mm_s,
                    "max_speed_mm_s",
                    &mut coupling.max_speed_mm_s,
                ),
            ];
            for (value, name, slot) in fields {
                if let Some(value) = value {
                    self.check(
                        at,
                        &key(&format!("coupling.{name}")),
                        value.is_finite() && value > 0.0,
                        "must be a positive number",
                    )?;
                    *slot = value;
                }
            }
        }
        let instrument = match &tool.instrument {
            None => crate::world::InstrumentSpec::Probe,
            Some(at) => self.instrument(i, at)?,
        };
        let shaft = match &tool.shaft {
            None => None,
            Some(at) => {
                let section = at.get_ref();
                self.check(
                    at,
                    &key("shaft.radius_mm"),
                    section.radius_mm.is_finite() && (0.1..=50.0).contains(&section.radius_mm),
                    "must be 0.1 to 50 mm",
                )?;
                self.check(
                    at,
                    &key("shaft.length_mm"),
                    section.length_mm.is_finite() && (1.0..=1000.0).contains(&section.length_mm),
                    "must be 1 to 1000 mm",
                )?;
                Some(ShaftSpec {
                    radius_mm: section.radius_mm,
                    length_mm: section.length_mm,
                })
            }
        };
        Ok(ToolSpec {
            name: tool.name.get_ref().clone(),
            device_id,
            shape,
            device_origin_in_world_mm: tool.device_origin_in_world_mm,
            max_force_n,
            coupling,
            instrument,
            shaft,
        })
    }

    /// An optional number: `default` when absent, else the value if it is finite and within `range`; else the
    /// error names `key` and its line.
    fn optional_in(
        &self,
        value: &Option<Spanned<f32>>,
        key: &str,
        range: std::ops::RangeInclusive<f32>,
        default: f32,
        says: &str,
    ) -> Result<f32, WorldError> {
        match value {
            None => Ok(default),
            Some(at) => {
                let v = *at.get_ref();
                self.check(at, key, v.is_finite() && range.contains(&v), says)?;
                Ok(v)
            }
        }
    }

    /// `value`, when given, into `slot` if it is finite and `ok`; else the error names `key`.
    fn take_checked<T>(
        &self,
        at: &Spanned<T>,
        key: &str,
        value: Option<f32>,
        ok: impl Fn(f32) -> bool,
        says: &str,
        slot: &mut f32,
    ) -> Result<(), WorldError> {
        if let Some(value) = value {
            self.check(at, key, value.is_finite() && ok(value), says)?;
            *slot = value;
        }
        Ok(())
    }

    /// An instrument's button mask (default button 1): at least one bit.
    fn button_mask<T>(
        &self,
        at: &Spanned<T>,
        key: &str,
        mask: Option<u32>,
    ) -> Result<u32, WorldError> {
        let mask = mask.unwrap_or(1);
        self.check(at, key, mask != 0, "must name at least one button bit")?;
        Ok(mask)
    }

    /// The `activation` keys of an instrument with jaws (a grasper, scissors): a button (default 1) or a
    /// gripper's angle with its hysteresis band, each key checked.
    fn jaw_activation(
        &self,
        i: usize,
        at: &Spanned<InstrumentSection>,
    ) -> Result<crate::world::JawActivation, WorldError> {
        use crate::world::{GraspSpec, JawActivation};
        let section = at.get_ref();
        let key = |k: &str| format!("tools[{i}].instrument.{k}");
        let rad = |deg: f32| deg.to_radians();
        let angle_keys = section.close_below_deg.is_some() || section.open_above_deg.is_some();
        let activation = match section.activation.unwrap_or(ActivationName::Button) {
            ActivationName::Button => {
                if angle_keys {
                    return Err(self.invalid(
                        at,
                        &key("close_below_deg"),
                        "the jaw angle thresholds need activation = \"angle\"",
                    ));
                }
                JawActivation::Button {
                    mask: self.button_mask(at, &key("button_mask"), section.button_mask)?,
                }
            }
            ActivationName::Angle => {
                if section.button_mask.is_some() {
                    return Err(self.invalid(
                        at,
                        &key("button_mask"),
                        "a button mask needs activation = \"button\"",
                    ));
                }
                let JawActivation::Angle {
                    mut close_below_rad,
                    mut open_above_rad,
                } = GraspSpec::ANGLE_DEFAULT
                else {
                    unreachable!("the angle default is an angle activation")
                };
                if let Some(deg) = section.close_below_deg {
                    close_below_rad = rad(deg);
                }
                if let Some(deg) = section.open_above_deg {
                    open_above_rad = rad(deg);
                }
                self.check(
                    at,
                    &key("close_below_deg"),
                    close_below_rad.is_finite() && close_below_rad >= 0.0,
                    "must be a number >= 0",
                )?;
                self.check(
                    at,
                    &key("open_above_deg"),
                    open_above_rad.is_finite() && open_above_rad > close_below_rad,
                    "must be above close_below_deg (the hysteresis band)",
                )?;
                JawActivation::Angle {
                    close_below_rad,
                    open_above_rad,
                }
            }
        };
        Ok(activation)
    }

    /// `tools[i].instrument`: every key checked for its kind and its range.
    fn instrument(
        &self,
        i: usize,
        at: &Spanned<InstrumentSection>,
    ) -> Result<crate::world::InstrumentSpec, WorldError> {
        use crate::world::{GraspSpec, InstrumentSpec};
        let section = at.get_ref();
        let key = |k: &str| format!("tools[{i}].instrument.{k}");
        // Which keys each kind takes; any other given key is refused by name.
        let given = [
            ("activation", section.activation.is_some()),
            ("button_mask", section.button_mask.is_some()),
            ("close_below_deg", section.close_below_deg.is_some()),
            ("open_above_deg", section.open_above_deg.is_some()),
            ("open_angle_deg", section.open_angle_deg.is_some()),
            ("jaw_length_mm", section.jaw_length_mm.is_some()),
            ("bite_mm", section.bite_mm.is_some()),
            ("slip_force_n", section.slip_force_n.is_some()),
            ("max_attachments", section.max_attachments.is_some()),
            ("burn_per_s", section.burn_per_s.is_some()),
            ("reach_mm", section.reach_mm.is_some()),
            ("edge_from_mm", section.edge_from_mm.is_some()),
            ("edge_to_mm", section.edge_to_mm.is_some()),
            ("cut_resistance_n", section.cut_resistance_n.is_some()),
            ("blade_length_mm", section.blade_length_mm.is_some()),
            ("hinge_mm", section.hinge_mm.is_some()),
        ];
        let (takes, kind_says): (&[&str], &str) = match section.kind {
            InstrumentKindName::Probe => (
                &[],
                "a probe has no jaws or tip: only a grasper or a cautery tool takes it",
            ),
            InstrumentKindName::Grasper => (
                &[
                    "activation",
                    "button_mask",
                    "close_below_deg",
                    "open_above_deg",
                    "open_angle_deg",
                    "jaw_length_mm",
                    "bite_mm",
                    "slip_force_n",
                    "max_attachments",
                ],
                "a grasper does not take it",
            ),
            InstrumentKindName::Cautery => (
                &["button_mask", "burn_per_s", "reach_mm"],
                "a cautery tool takes button_mask, burn_per_s and reach_mm",
            ),
            InstrumentKindName::Scalpel => (
                &["edge_from_mm", "edge_to_mm"],
                "a scalpel takes edge_from_mm and edge_to_mm (the drag of cutting is the tissue's: \
                 [objects.material] cut_resistance_n)",
            ),
            InstrumentKindName::Scissors => (
                &[
                    "activation",
                    "button_mask",
                    "close_below_deg",
                    "open_above_deg",
                    "open_angle_deg",
                    "blade_length_mm",
                    "hinge_mm",
                ],
                "scissors take activation, button_mask, close_below_deg, open_above_deg, open_angle_deg, \
                 blade_length_mm and hinge_mm",
            ),
        };
        if let Some((name, _)) = given
            .iter()
            .find(|(name, given)| *given && !takes.contains(name))
        {
            return Err(self.invalid(at, &key(name), kind_says));
        }
        match section.kind {
            InstrumentKindName::Probe => Ok(InstrumentSpec::Probe),
            InstrumentKindName::Scalpel => {
                let mut scalpel = crate::world::ScalpelSpec::DEFAULT;
                for (k, (name, value)) in [
                    ("edge_from_mm", section.edge_from_mm),
                    ("edge_to_mm", section.edge_to_mm),
                ]
                .into_iter()
                .enumerate()
                {
                    if let Some(p) = value {
                        self.check(
                            at,
                            &key(name),
                            p.iter().all(|c| c.is_finite() && c.abs() <= 500.0),
                            "must be three finite numbers within 500 mm of the tool origin",
                        )?;
                        scalpel.edge_mm[k] = p;
                    }
                }
                let [a, b] = scalpel.edge_mm;
                let length =
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                self.check(
                    at,
                    &key("edge_to_mm"),
                    length >= 0.1,
                    "the edge must be at least 0.1 mm long (edge_from_mm and edge_to_mm too close)",
                )?;
                Ok(InstrumentSpec::Scalpel(scalpel))
            }
            InstrumentKindName::Scissors => {
                let mut scissors = crate::world::ScissorsSpec::DEFAULT;
                scissors.activation = self.jaw_activation(i, at)?;
                self.take_checked(
                    at,
                    &key("open_angle_deg"),
                    section.open_angle_deg.map(f32::to_radians),
                    |v| v > 2.0 * crate::world::ScissorsSpec::CROSSING_RAD && v <= 1.6,
                    "must be more than 6 and at most about 90 degrees",
                    &mut scissors.open_angle_rad,
                )?;
                self.take_checked(
                    at,
                    &key("blade_length_mm"),
                    section.blade_length_mm,
                    |v| (1.0..=200.0).contains(&v),
                    "must be 1 to 200 mm",
                    &mut scissors.blade_length_mm,
                )?;
                if let Some(p) = section.hinge_mm {
                    self.check(
                        at,
                        &key("hinge_mm"),
                        p.iter().all(|c| c.is_finite() && c.abs() <= 500.0),
                        "must be three finite numbers within 500 mm of the tool origin",
                    )?;
                    scissors.hinge_mm = p;
                }
                Ok(InstrumentSpec::Scissors(scissors))
            }
            InstrumentKindName::Cautery => {
                let mut cautery = crate::world::CauterySpec::DEFAULT;
                cautery.button_mask =
                    self.button_mask(at, &key("button_mask"), section.button_mask)?;
                self.take_checked(
                    at,
                    &key("burn_per_s"),
                    section.burn_per_s,
                    |rate| rate > 0.0 && rate <= 100_000.0,
                    "must be a positive number of burn levels per second, at most 100000",
                    &mut cautery.burn_per_s,
                )?;
                self.take_checked(
                    at,
                    &key("reach_mm"),
                    section.reach_mm,
                    |reach| (0.0..=10.0).contains(&reach),
                    "must be 0 to 10 mm",
                    &mut cautery.reach_mm,
                )?;
                Ok(InstrumentSpec::Cautery(cautery))
            }
            InstrumentKindName::Grasper => {
                let mut grasp = GraspSpec::DEFAULT;
                let rad = |deg: f32| deg.to_radians();
                grasp.activation = self.jaw_activation(i, at)?;
                let positive = [
                    (
                        "open_angle_deg",
                        section.open_angle_deg.map(rad),
                        &mut grasp.open_angle_rad,
                        180.0f32.to_radians(),
                    ),
                    (
                        "jaw_length_mm",
                        section.jaw_length_mm,
                        &mut grasp.jaw_length_mm,
                        200.0,
                    ),
                    (
                        "slip_force_n",
                        section.slip_force_n,
                        &mut grasp.slip_force_n,
                        100.0,
                    ),
                ];
                for (name, value, slot, most) in positive {
                    self.take_checked(
                        at,
                        &key(name),
                        value,
                        |v| v > 0.0 && v <= most,
                        &format!("must be a positive number, at most {most}"),
                        slot,
                    )?;
                }
                self.take_checked(
                    at,
                    &key("bite_mm"),
                    section.bite_mm,
                    |bite| (0.0..=10.0).contains(&bite),
                    "must be 0 to 10 mm",
                    &mut grasp.bite_mm,
                )?;
                if let Some(most) = section.max_attachments {
                    self.check(
                        at,
                        &key("max_attachments"),
                        (1..=crate::interaction::MAX_ATTACHMENTS).contains(&most),
                        &format!("must be 1 to {}", crate::interaction::MAX_ATTACHMENTS),
                    )?;
                    grasp.max_attachments = most;
                }
                Ok(InstrumentSpec::Grasper(grasp))
            }
        }
    }
}

impl Context<'_> {
    /// Object `i`'s ticks per step from its optional `step_hz`: the tick rate must be a whole multiple of it,
    /// at most [`MAX_TICKS_PER_STEP`] times it.
    fn ticks_per_step(
        &self,
        i: usize,
        object: &ObjectSection,
        tick_dt_s: f32,
    ) -> Result<u32, WorldError> {
        let Some(at) = &object.step_hz else {
            return Ok(1);
        };
        let key = format!("objects[{i}].step_hz");
        let step_hz = *at.get_ref();
        let tick_hz = 1.0 / f64::from(tick_dt_s);
        self.check(
            at,
            &key,
            // The tick rate comes back from the f32 tick period: a rate equal to it is within rounding.
            step_hz.is_finite() && step_hz > 0.0 && step_hz <= tick_hz * (1.0 + 1e-6),
            &format!("must be a positive rate no higher than sim.tick_hz = {tick_hz:.0} Hz (got {step_hz})"),
        )?;
        let ratio = tick_hz / step_hz;
        let ticks = ratio.round();
        self.check(
            at,
            &key,
            (ratio - ticks).abs() <= 1e-6 * ratio && ticks <= f64::from(MAX_TICKS_PER_STEP),
            &format!(
                "must divide sim.tick_hz = {tick_hz:.0} Hz a whole number of times, at most {MAX_TICKS_PER_STEP} \
                 (got {step_hz} Hz: {ratio:.3} ticks a step)"
            ),
        )?;
        Ok(ticks as u32)
    }

    /// What a multi-rate object (`step_hz` below the tick rate) cannot do yet: a region of deformation (it
    /// follows the tools tick by tick), tearing and burn shrink (they change the model the object's own thread
    /// steps).
    fn multirate_combinations(
        &self,
        i: usize,
        object: &ObjectSection,
        material: &MaterialSpec,
        ticks_per_step: u32,
    ) -> Result<(), WorldError> {
        let Some(at) = object.step_hz.as_ref().filter(|_| ticks_per_step > 1) else {
            return Ok(());
        };
        let key = format!("objects[{i}].step_hz");
        self.check(
            at,
            &key,
            object.region.is_none(),
            "cannot be combined with `region`: a region follows the tools every tick; drop one of them",
        )?;
        self.check(
            at,
            &key,
            material.tear_strain.is_none() && material.burn_shrink == 0.0,
            "cannot be combined with material.tear_strain or material.burn_shrink: a multi-rate object's model \
             is stepped on its own thread and cannot change under it",
        )?;
        Ok(())
    }

    /// The optional `region` table of object `i`, and the combinations region tracking cannot simulate.
    fn region(
        &self,
        i: usize,
        object: &ObjectSection,
        material: &MaterialSpec,
        gravity_mm_per_s2: [f32; 3],
    ) -> Result<Option<RegionParams>, WorldError> {
        let Some(at) = &object.region else {
            return Ok(None);
        };
        let key = format!("objects[{i}].region");
        let threshold = &at.get_ref().threshold_mm;
        let threshold_mm = *threshold.get_ref();
        self.check(
            threshold,
            &format!("{key}.threshold_mm"),
            threshold_mm.is_finite() && threshold_mm > 0.0 && threshold_mm <= 1.0,
            &format!("must be in (0, 1] mm (got {threshold_mm})"),
        )?;
        self.check(
            at,
            &key,
            material.global_bulk_modulus_n_per_mm2 == 0.0,
            "cannot be combined with material.bulk_modulus_kpa: the global volume term couples every surface node",
        )?;
        self.check(
            at,
            &key,
            gravity_mm_per_s2 == [0.0; 3],
            "needs sim.gravity_mm_per_s2 = [0, 0, 0]: gravity moves the whole object, not a region",
        )?;
        Ok(Some(RegionParams { threshold_mm }))
    }
}

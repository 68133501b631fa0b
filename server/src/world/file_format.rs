//! The serde shape of a world TOML file. Unknown keys are refused; numbers that need a range check carry
//! their source span so the loader can name the line.

use serde::Deserialize;
use toml::Spanned;

use crate::tissue::IntegratorName;

/// Length unit of a mesh file; converted to millimetres at load.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Millimetres (the world unit).
    Mm,
    /// Centimetres.
    Cm,
    /// Metres.
    M,
}

impl LengthUnit {
    /// Millimetres per unit.
    pub fn to_mm(self) -> f32 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::Cm => 10.0,
            LengthUnit::M => 1000.0,
        }
    }
}

/// What of an object's surface the tools keep out of their tips.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ToolContactName {
    /// The surface's nodes (the default: enough for a surface finer than the tools).
    #[default]
    Nodes,
    /// The nodes and the triangles between them (a coarse surface: an organ's 3-5 mm under a 4 mm probe).
    NodesAndTriangles,
}

/// How an object's elasticity is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ElasticModel {
    /// Springs along the mesh edges (per-edge N/mm, or calibrated from Young's modulus). The default.
    #[default]
    MassSpring,
    /// Corotational linear finite elements on the tetrahedra, from Young's modulus and Poisson's ratio.
    FemCorotational,
}

impl ElasticModel {
    /// The name the world file uses.
    pub fn as_str(self) -> &'static str {
        match self {
            ElasticModel::MassSpring => "mass-spring",
            ElasticModel::FemCorotational => "fem-corotational",
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct WorldFile {
    pub scene: Spanned<String>,
    #[serde(default)]
    pub sim: SimSection,
    #[serde(default)]
    pub collision: CollisionSection,
    #[serde(default)]
    pub objects: Vec<ObjectSection>,
    #[serde(default)]
    pub tools: Vec<ToolSection>,
    #[serde(default)]
    pub ties: Vec<Spanned<TieSection>>,
    #[serde(default)]
    pub exercise: Option<Spanned<ExerciseSection>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ExerciseSection {
    pub name: Spanned<String>,
    pub kind: crate::world::ExerciseKind,
    pub time_limit_s: Spanned<f64>,
    #[serde(default)]
    pub depth_limit_mm: Option<Spanned<f32>>,
    #[serde(default)]
    pub targets: Option<Spanned<Vec<Spanned<TargetSection>>>>,
    #[serde(default)]
    pub samples: Option<Spanned<Vec<String>>>,
    #[serde(default)]
    pub wound: Option<Spanned<[String; 2]>>,
    #[serde(default)]
    pub knot: Option<Spanned<bool>>,
    #[serde(default)]
    pub pattern: Option<Spanned<PatternSection>>,
}

/// A pattern-cutting exercise's marked circles.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PatternSection {
    pub object: String,
    pub centre_mm: [f32; 3],
    pub inner_radius_mm: f32,
    pub outer_radius_mm: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TargetSection {
    pub at_mm: [f32; 3],
    pub radius_mm: f32,
    #[serde(default)]
    pub tool: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TieSection {
    /// `[a, b]`: each node of `a` is tied to the nearest node of `b` within `within_mm`.
    pub objects: [String; 2],
    pub within_mm: f32,
    pub stiffness_n_per_mm: f32,
    #[serde(default)]
    pub damping_n_s_per_mm: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SimSection {
    #[serde(default = "default_tick_hz")]
    pub tick_hz: Spanned<f64>,
    #[serde(default = "default_publish_hz")]
    pub publish_hz: Spanned<f64>,
    #[serde(default = "default_pose_timeout_s")]
    pub pose_timeout_s: Spanned<f64>,
    #[serde(default = "default_gravity")]
    pub gravity_mm_per_s2: Spanned<[f32; 3]>,
    /// Threads the tissue passes spread over (absent: what the machine can spare).
    #[serde(default)]
    pub threads: Option<Spanned<i64>>,
}

impl Default for SimSection {
    fn default() -> Self {
        Self {
            tick_hz: default_tick_hz(),
            publish_hz: default_publish_hz(),
            pose_timeout_s: default_pose_timeout_s(),
            gravity_mm_per_s2: Spanned::new(0..0, [0.0; 3]),
            threads: None,
        }
    }
}

fn default_tick_hz() -> Spanned<f64> {
    Spanned::new(0..0, 1000.0)
}
fn default_gravity() -> Spanned<[f32; 3]> {
    Spanned::new(0..0, [0.0; 3])
}
fn default_publish_hz() -> Spanned<f64> {
    Spanned::new(0..0, 60.0)
}
fn default_pose_timeout_s() -> Spanned<f64> {
    Spanned::new(0..0, 0.1)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CollisionSection {
    #[serde(default = "default_margin_mm")]
    pub margin_mm: Spanned<f32>,
}

impl Default for CollisionSection {
    fn default() -> Self {
        Self {
            margin_mm: default_margin_mm(),
        }
    }
}

fn default_margin_mm() -> Spanned<f32> {
    Spanned::new(0..0, 2.0)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjectSection {
    pub name: Spanned<String>,
    /// `.obj` (a surface) or `.msh` (Gmsh MSH 4.1 tetrahedra: a volume).
    pub mesh: Spanned<String>,
    pub units: LengthUnit,
    /// Where the mesh's origin sits in the world, mm (default: at the world origin).
    #[serde(default)]
    pub offset_mm: Option<Spanned<[f32; 3]>>,
    /// Turn an OBJ surface into a volume: `{ thickness_mm, layers }`.
    #[serde(default)]
    pub extrude: Option<Spanned<ExtrudeSection>>,
    /// `mass-spring` (default) or `fem-corotational`.
    #[serde(default)]
    pub model: Option<Spanned<ElasticModel>>,
    pub integrator: Spanned<IntegratorName>,
    pub dt_s: Spanned<f32>,
    /// The object's own step rate, Hz, when lower than the tick's: it steps every `tick_hz / step_hz` ticks
    /// on its own thread, and the tick renders it through its local model in between (default: every tick).
    #[serde(default)]
    pub step_hz: Option<Spanned<f64>>,
    #[serde(default)]
    pub solver_iterations: Option<Spanned<u32>>,
    #[serde(default = "default_quant_margin_mm")]
    pub quant_margin_mm: Spanned<f32>,
    /// A vertex is re-sent to viewers once they hold it further than this from its position, mm (default
    /// 0.01: the replicas' error bound; 0 sends every change of its quantized position).
    #[serde(default = "default_delta_tolerance_mm")]
    pub delta_tolerance_mm: Spanned<f32>,
    /// A table of material keys, or a preset's name (`material = "liver"`).
    pub material: Spanned<MaterialValue>,
    #[serde(default)]
    pub fixed: Vec<Spanned<FixedSection>>,
    /// Region of deformation: integrate only the part that moves, `{ threshold_mm }` (default: off).
    #[serde(default)]
    pub region: Option<Spanned<RegionSection>>,
    /// What of the surface the tools keep out of their tips: `"nodes"` (default) or `"nodes-and-triangles"`.
    #[serde(default)]
    pub tool_contact: Option<Spanned<ToolContactName>>,
}

fn default_delta_tolerance_mm() -> Spanned<f32> {
    Spanned::new(0..0, 0.01)
}

fn default_quant_margin_mm() -> Spanned<f32> {
    Spanned::new(0..0, 40.0)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ExtrudeSection {
    /// Depth of the layer of volume under the surface (along minus its normal), mm.
    pub thickness_mm: Spanned<f32>,
    /// Tetrahedra layers through the thickness (1..=16).
    #[serde(default = "default_extrude_layers")]
    pub layers: Spanned<i64>,
}

fn default_extrude_layers() -> Spanned<i64> {
    Spanned::new(0..0, 1)
}

/// `material = "liver"` (a preset) or `material = { ... }` / `[objects.material]` (a table).
#[derive(Debug)]
pub(crate) enum MaterialValue {
    Preset(String),
    Table(Box<MaterialSection>),
}

impl<'de> Deserialize<'de> for MaterialValue {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Either;
        impl<'de> serde::de::Visitor<'de> for Either {
            type Value = MaterialValue;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a material preset's name (liver, skin, fat, muscle) or a table of material keys")
            }
            fn visit_str<E: serde::de::Error>(self, name: &str) -> Result<MaterialValue, E> {
                Ok(MaterialValue::Preset(name.to_owned()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<MaterialValue, A::Error> {
                MaterialSection::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(|m| MaterialValue::Table(Box::new(m)))
            }
        }
        deserializer.deserialize_any(Either)
    }
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MaterialSection {
    /// A preset from worlds/material_presets.toml whose modulus, ratio and density fill the keys not given.
    #[serde(default)]
    pub preset: Option<Spanned<String>>,
    pub mass_kg: Option<Spanned<f32>>,
    pub density_kg_per_m3: Option<Spanned<f32>>,
    pub thickness_mm: Option<Spanned<f32>>,
    #[serde(default)]
    pub stiffness_n_per_mm: Option<Spanned<f32>>,
    #[serde(default)]
    pub damping_n_s_per_mm: Option<Spanned<f32>>,
    /// Young's modulus, kPa (with `poisson_ratio`).
    #[serde(default)]
    pub youngs_modulus_kpa: Option<Spanned<f32>>,
    /// Poisson's ratio, 0 to 0.499 (with `youngs_modulus_kpa`).
    #[serde(default)]
    pub poisson_ratio: Option<Spanned<f32>>,
    #[serde(default)]
    pub anchor_stiffness_n_per_mm: Option<Spanned<f32>>,
    #[serde(default)]
    pub drag_per_s: Option<Spanned<f32>>,
    #[serde(default)]
    pub law: Option<Spanned<LawSection>>,
    /// Global volume preservation (closed surfaces), kPa.
    #[serde(default)]
    pub bulk_modulus_kpa: Option<Spanned<f32>>,
    /// Per-tetrahedron volume preservation, kPa.
    #[serde(default)]
    pub tet_bulk_modulus_kpa: Option<Spanned<f32>>,
    /// A sheet tears where a spring is stretched past this strain (length over rest, minus one).
    #[serde(default)]
    pub tear_strain: Option<Spanned<f32>>,
    /// Drag a sharp edge feels against its motion while it cuts this tissue, N.
    #[serde(default)]
    pub cut_resistance_n: Option<Spanned<f32>>,
    /// How a blade cuts this tissue: along the mesh's own facets, or following the blade.
    #[serde(default)]
    pub cut: Option<Spanned<CutSection>>,
    /// Share of its rest length a spring loses between fully burnt ends (cautery shrinks tissue), 0 to 0.5.
    #[serde(default)]
    pub burn_shrink: Option<Spanned<f32>>,
    /// Coulomb friction coefficient between tools and this tissue (0: frictionless).
    #[serde(default)]
    pub friction_coefficient: Option<Spanned<f32>>,
    /// A suture needle's tip punctures the surface past this force along its direction, N.
    #[serde(default)]
    pub puncture_force_n: Option<Spanned<f32>>,
    /// ... and only within this angle of the surface's normal, degrees.
    #[serde(default)]
    pub puncture_max_angle_deg: Option<Spanned<f32>>,
    /// Coulomb friction of a needle sliding through this tissue.
    #[serde(default)]
    pub needle_friction: Option<Spanned<f32>>,
    /// A suture's thread pulling on this tissue at a hole harder than this tears it there, N.
    #[serde(default)]
    pub suture_tear_n: Option<Spanned<f32>>,
}

/// `cut = "facets"` (the default) or `"follow-blade"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum CutSection {
    /// Seams open along the mesh's own edges and faces the blade's path separates.
    Facets,
    /// The edges the blade crosses are split where it crosses them, and the cut opens along its path.
    FollowBlade,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "kebab-case")]
pub(crate) enum LawSection {
    Linear,
    PiecewiseLinear {
        knee_strain: f32,
        stiffness_ratio: f32,
    },
    Exponential {
        stiffening: f32,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "lowercase")]
pub(crate) enum FixedSection {
    Box {
        min_mm: [f32; 3],
        max_mm: [f32; 3],
    },
    Plane {
        point_mm: [f32; 3],
        normal: [f32; 3],
        #[serde(default)]
        tolerance_mm: f32,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ToolSection {
    pub name: Spanned<String>,
    pub device: Spanned<String>,
    pub shape: Spanned<ShapeSection>,
    #[serde(default)]
    pub device_origin_in_world_mm: [f32; 3],
    #[serde(default = "default_max_force_n")]
    pub max_force_n: Spanned<f32>,
    /// Virtual coupling of the tool to its device pose (defaults: `haptics::CouplingParams::default`).
    #[serde(default)]
    pub coupling: Option<Spanned<CouplingSection>>,
    /// What the tool does beyond pushing (default: a probe).
    #[serde(default)]
    pub instrument: Option<Spanned<InstrumentSection>>,
    /// The instrument's shaft: a capsule from the tool origin up its local +z, which pushes tissue too.
    #[serde(default)]
    pub shaft: Option<Spanned<ShaftSection>>,
}

/// `shaft = { radius_mm, length_mm }` of a tool.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ShaftSection {
    pub radius_mm: f32,
    pub length_mm: f32,
}

/// `instrument = { kind = "probe" | "grasper" | "cautery" | "scalpel" | "scissors", ... }` of a tool (see
/// `world::instrument`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct InstrumentSection {
    pub kind: InstrumentKindName,
    /// Grasper: `"button"` (default) or `"angle"`.
    pub activation: Option<ActivationName>,
    /// Grasper, `activation = "button"`: button bits that close the jaws (default 1); cautery: that switch the
    /// current on.
    pub button_mask: Option<u32>,
    /// Grasper, `activation = "angle"`: close below, open above, degrees.
    pub close_below_deg: Option<f32>,
    pub open_above_deg: Option<f32>,
    pub open_angle_deg: Option<f32>,
    pub jaw_length_mm: Option<f32>,
    pub bite_mm: Option<f32>,
    pub slip_force_n: Option<f32>,
    pub max_attachments: Option<u16>,
    /// Cautery: burn levels per second while touching (0-255 scale).
    pub burn_per_s: Option<f32>,
    /// Cautery: surface this close to the tip burns too, mm.
    pub reach_mm: Option<f32>,
    /// Scalpel: the sharp edge's ends in the tool frame, mm.
    pub edge_from_mm: Option<[f32; 3]>,
    pub edge_to_mm: Option<[f32; 3]>,
    /// Refused: the drag of cutting is the tissue's (`[objects.material] cut_resistance_n`).
    pub cut_resistance_n: Option<f32>,
    /// Scissors: each blade's length from the hinge, mm.
    pub blade_length_mm: Option<f32>,
    /// Scissors: the hinge in the tool frame, mm.
    pub hinge_mm: Option<[f32; 3]>,
    /// Needle driver: the needle's arc radius, mm.
    pub needle_radius_mm: Option<f32>,
    /// Needle driver: the needle's sweep, degrees.
    pub needle_sweep_deg: Option<f32>,
    /// Needle driver: the needle's wire diameter, mm.
    pub needle_diameter_mm: Option<f32>,
    /// Needle driver: where along the needle the jaws hold it, degrees from the tail.
    pub grasp_at_deg: Option<f32>,
    /// Needle driver: the thread's length, mm (0: no thread).
    pub thread_length_mm: Option<f32>,
    /// Needle driver: the thread's segments.
    pub thread_segments: Option<u16>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum InstrumentKindName {
    Probe,
    Grasper,
    Cautery,
    Scalpel,
    Scissors,
    #[serde(rename = "needle_driver")]
    NeedleDriver,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum ActivationName {
    Button,
    Angle,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CouplingSection {
    pub stiffness_n_per_mm: Option<f32>,
    pub damping_n_s_per_mm: Option<f32>,
    pub max_speed_mm_s: Option<f32>,
}

fn default_max_force_n() -> Spanned<f32> {
    Spanned::new(0..0, 3.3)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "lowercase")]
pub(crate) enum ShapeSection {
    Sphere { radius_mm: f32 },
    Capsule { half_length_mm: f32, radius_mm: f32 },
    Mesh { mesh: String, units: LengthUnit },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RegionSection {
    /// A node farther than this from rest, or moving more than this per tick, keeps its level active, mm.
    pub threshold_mm: Spanned<f32>,
}

//! What a deformable object is made of, as the engine takes it: its mesh, integrator, material and fixed nodes.
//! A world file's `[[objects]]` table is one front end that produces these; a test or a tool builds them in code.
//!
//! Owns: [`ObjectSpec`], [`MaterialSpec`], [`MassSpec`], [`SpringCalibration`], [`FixedSelection`]. Must not:
//! read files or know TOML (the world-file layer validates the file and fills these).

use super::{IntegratorName, RegionParams, SpringLaw, SurfaceMesh};

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
    /// Tools keep the surface's triangles out of a ball or capsule tip, not only its nodes
    /// (`interaction::probe`'s triangle pass): for a surface whose nodes are further apart than a tool is wide.
    pub triangle_contact: bool,
    /// Ticks per step of the object (1: it steps every tick; `N > 1`: a multi-rate object, stepped every `N`
    /// ticks with `N` ticks' time, on its own thread: see [`crate::multirate`]).
    pub ticks_per_step: u32,
}

impl ObjectSpec {
    /// The largest step (s) at which this object's explicit integrator is stable at its stiffness, damping
    /// and mass, under `gravity_mm_per_s2`; `None` for a method without a bound (implicit, quasi-static,
    /// XPBD). A world file's `dt_s` above it is refused; a scene built in code checks it here.
    pub fn max_stable_dt_s(&self, gravity_mm_per_s2: [f32; 3]) -> Option<f32> {
        let model = super::MassSpringModel::build(self, super::Vec3::from(gravity_mm_per_s2));
        super::stability::max_stable_dt_s(self.integrator, &model)
    }
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
    /// A blade cutting this tissue splits the edges it crosses where it crosses them (`cut = "follow-blade"`),
    /// rather than opening the mesh's own facets along its path.
    pub cut_follows_blade: bool,
    /// Share of its rest length a spring loses when both its ends are fully burnt (0: burns do not shrink).
    pub burn_shrink: f32,
    /// Coulomb friction coefficient between a tool and this tissue (0: frictionless).
    pub friction_coefficient: f32,
    /// How the tissue answers a suture needle (puncture force and angle, needle friction).
    pub puncture: super::PunctureSpec,
    /// Corotational finite elements (`model = "fem-corotational"`); the springs then carry no stiffness.
    pub fem: Option<super::fem::FemMaterial>,
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

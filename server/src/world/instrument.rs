//! Instruments: what a tool does to tissue beyond pushing it, as the world file describes it.
//!
//! Owns: [`InstrumentSpec`] (the kind of instrument a tool is, with its parameters), [`JawActivation`] (which
//! part of a device pose opens and closes the jaws, with thresholds and hysteresis) and the defaults of each
//! kind. The loader fills them from `instrument = { kind = ..., ... }` in a `[[tools]]` table; the sim core
//! (`interaction::jaws`, `interaction::grasp`) runs them.
//!
//! Geometry. A tool's `shape` is its blunt body: it probes as before. A grasper's two jaws are that body's two
//! halves on either side of the tool's local `y = 0` plane, hinged about the tool's local x axis at the back of
//! the body: closing them takes the tissue the body touches on both sides (so a body that grazes tissue with one
//! side only cannot grasp). `jaw_length_mm` and `open_angle_deg` are how the viewers draw them. A cautery
//! tool's whole body is its active tip: while its button is held, the surface it touches burns. A scalpel's
//! sharp edge is a segment in the tool frame that passes through tissue and cuts what it sweeps; its body is
//! the blunt back.

/// What a tool is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InstrumentSpec {
    /// Pushes tissue (the default).
    Probe,
    /// Jaws that hold tissue while closed.
    Grasper(GraspSpec),
    /// An active tip (a hook) that burns the tissue it touches while a button is held.
    Cautery(CauterySpec),
    /// A sharp edge that cuts the tissue it sweeps through; the body (its blunt back) probes.
    Scalpel(ScalpelSpec),
}

impl InstrumentSpec {
    /// The kind's name in the world file and on the wire.
    pub fn kind_name(&self) -> &'static str {
        match self {
            InstrumentSpec::Probe => "probe",
            InstrumentSpec::Grasper(_) => "grasper",
            InstrumentSpec::Cautery(_) => "cautery",
            InstrumentSpec::Scalpel(_) => "scalpel",
        }
    }

    /// The grasp parameters, for a grasper.
    pub fn grasp(&self) -> Option<&GraspSpec> {
        match self {
            InstrumentSpec::Grasper(g) => Some(g),
            InstrumentSpec::Probe | InstrumentSpec::Cautery(_) | InstrumentSpec::Scalpel(_) => None,
        }
    }

    /// The cautery parameters, for a cautery tool.
    pub fn cautery(&self) -> Option<&CauterySpec> {
        match self {
            InstrumentSpec::Cautery(c) => Some(c),
            InstrumentSpec::Probe | InstrumentSpec::Grasper(_) | InstrumentSpec::Scalpel(_) => None,
        }
    }

    /// The blade, for a scalpel.
    pub fn scalpel(&self) -> Option<&ScalpelSpec> {
        match self {
            InstrumentSpec::Scalpel(s) => Some(s),
            InstrumentSpec::Probe | InstrumentSpec::Grasper(_) | InstrumentSpec::Cautery(_) => None,
        }
    }
}

/// A scalpel's blade: a sharp edge, a segment in the tool frame. Between two ticks the edge sweeps a surface;
/// tissue it sweeps through is cut along the mesh's facets (`interaction::cut`). The edge does not push
/// tissue (it passes through it); the tool's `shape` is the blunt back and probes as any body does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalpelSpec {
    /// The edge's two ends in the tool frame, mm.
    pub edge_mm: [[f32; 3]; 2],
    /// Drag the tool feels against its motion while the edge cuts, N.
    pub cut_resistance_n: f32,
}

impl ScalpelSpec {
    /// Defaults of `kind = "scalpel"`: an 8 mm edge from 1 mm to 9 mm below the tool origin along its local
    /// -z (below a small blunt back at the origin), 0.15 N of drag while cutting.
    pub const DEFAULT: ScalpelSpec = ScalpelSpec {
        edge_mm: [[0.0, 0.0, -1.0], [0.0, 0.0, -9.0]],
        cut_resistance_n: 0.15,
    };
}

/// A cautery tool's parameters: its whole body is the active tip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CauterySpec {
    /// Button bits that switch the current on (any of them held).
    pub button_mask: u32,
    /// How fast a touched vertex's burn rises, levels per second (0-255 scale: 255 is charred).
    pub burn_per_s: f32,
    /// Surface this close to the tip (outside it) burns too, mm.
    pub reach_mm: f32,
}

impl CauterySpec {
    /// Defaults of `kind = "cautery"`: button 1, 400 levels/s (charred after about 0.64 s of contact), 0.3 mm.
    pub const DEFAULT: CauterySpec = CauterySpec {
        button_mask: 1,
        burn_per_s: 400.0,
        reach_mm: 0.3,
    };
}

/// Which part of the device pose drives the jaws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JawActivation {
    /// A stylus button (a Touch has no jaw): held closes the jaws, released opens them. `mask` selects the
    /// button bits (`DevicePose.buttons`); any of them held counts.
    Button {
        /// Button bits that close the jaws.
        mask: u32,
    },
    /// A gripper's measured jaw angle (`DevicePose.jaw_angle_rad`): closed below `close_below_rad`, open again
    /// only above `open_above_rad` (hysteresis: a trembling grip does not chatter).
    Angle {
        /// The jaws close when the angle falls below this, rad.
        close_below_rad: f32,
        /// Closed jaws open when the angle rises above this, rad (> `close_below_rad`).
        open_above_rad: f32,
    },
}

/// A grasper's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspSpec {
    /// What opens and closes the jaws.
    pub activation: JawActivation,
    /// Opening of the open jaws, rad (drawn by the viewers; a button-driven jaw slews between 0 and this).
    pub open_angle_rad: f32,
    /// Length of each jaw, mm (drawn by the viewers).
    pub jaw_length_mm: f32,
    /// Nodes this close to the body (outside it) when the jaws close are taken too, mm: the jaws draw them in.
    pub bite_mm: f32,
    /// An attachment whose reaction exceeds this lets go (the tissue slips out of the jaws), N.
    pub slip_force_n: f32,
    /// Most material points one grasp holds.
    pub max_attachments: u16,
}

impl GraspSpec {
    /// Defaults of `kind = "grasper"`: a button closes a 40-degree, 8 mm jaw; 0.5 mm bite; 0.3 N per
    /// attachment before it slips; at most 64 points held.
    pub const DEFAULT: GraspSpec = GraspSpec {
        activation: JawActivation::Button { mask: 1 },
        open_angle_rad: 40.0 * std::f32::consts::PI / 180.0,
        jaw_length_mm: 8.0,
        bite_mm: 0.5,
        slip_force_n: 0.3,
        max_attachments: 64,
    };

    /// Defaults of `activation = "angle"`: close below 10 degrees, open above 20.
    pub const ANGLE_DEFAULT: JawActivation = JawActivation::Angle {
        close_below_rad: 10.0 * std::f32::consts::PI / 180.0,
        open_above_rad: 20.0 * std::f32::consts::PI / 180.0,
    };
}

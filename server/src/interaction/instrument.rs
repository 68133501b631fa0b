//! Instruments: what a tool does to tissue beyond pushing it, as the engine takes it (a world file's
//! `instrument = { kind = ... }` is one front end that fills these).
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
//! the blunt back. A pair of scissors has two sharp blades hinged about the tool's local x axis at `hinge_mm`,
//! running along its local -z and opening in its local y-z plane: as the jaws close, each blade sweeps the
//! part of the opening it passes through and cuts what it sweeps (the blades shear past each other by
//! [`ScissorsSpec::CROSSING_RAD`] when closed, so tissue between them is cut when they meet). Moving open
//! scissors cuts nothing; the body (`shape`) probes. A needle driver's jaws hold a curved needle at a fixed
//! pose (`interaction::suture::NeedleDriverSpec` says where); the body is the jaws and probes.

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
    /// Two sharp blades that cut what lies between them as they close; the body probes.
    Scissors(ScissorsSpec),
    /// Jaws holding a curved needle whose sharp tip punctures tissue (`interaction::suture`); the body (the
    /// jaws) probes.
    NeedleDriver(super::suture::NeedleDriverSpec),
}

impl InstrumentSpec {
    /// The kind's name in the world file and on the wire.
    pub fn kind_name(&self) -> &'static str {
        match self {
            InstrumentSpec::Probe => "probe",
            InstrumentSpec::Grasper(_) => "grasper",
            InstrumentSpec::Cautery(_) => "cautery",
            InstrumentSpec::Scalpel(_) => "scalpel",
            InstrumentSpec::Scissors(_) => "scissors",
            InstrumentSpec::NeedleDriver(_) => "needle_driver",
        }
    }

    /// What drives the jaws and how far they open (rad), for an instrument with jaws (a grasper, scissors).
    pub fn jaws(&self) -> Option<(JawActivation, f32)> {
        match self {
            InstrumentSpec::Grasper(g) => Some((g.activation, g.open_angle_rad)),
            InstrumentSpec::Scissors(s) => Some((s.activation, s.open_angle_rad)),
            InstrumentSpec::Probe
            | InstrumentSpec::Cautery(_)
            | InstrumentSpec::Scalpel(_)
            | InstrumentSpec::NeedleDriver(_) => None,
        }
    }

    /// How far the tool reaches from its origin, mm, given its body's reach `body_reach_mm`: a scalpel's
    /// edge and scissors' open blades reach beyond the body (a tool enters the scene clear of the tissue by
    /// this).
    pub fn reach_mm(&self, body_reach_mm: f32) -> f32 {
        let norm = |p: &[f32; 3]| crate::tissue::Vec3::from(*p).norm();
        match self {
            InstrumentSpec::Scalpel(s) => s.edge_mm.iter().map(norm).fold(body_reach_mm, f32::max),
            InstrumentSpec::Scissors(s) => s
                .blades_mm(s.open_angle_rad)
                .iter()
                .flatten()
                .map(norm)
                .fold(body_reach_mm, f32::max),
            InstrumentSpec::NeedleDriver(n) => n.reach_mm().max(body_reach_mm),
            InstrumentSpec::Probe | InstrumentSpec::Grasper(_) | InstrumentSpec::Cautery(_) => {
                body_reach_mm
            }
        }
    }

    /// The grasp parameters, for a grasper.
    pub fn grasp(&self) -> Option<&GraspSpec> {
        match self {
            InstrumentSpec::Grasper(g) => Some(g),
            _ => None,
        }
    }

    /// The cautery parameters, for a cautery tool.
    pub fn cautery(&self) -> Option<&CauterySpec> {
        match self {
            InstrumentSpec::Cautery(c) => Some(c),
            _ => None,
        }
    }

    /// The blade, for a scalpel.
    pub fn scalpel(&self) -> Option<&ScalpelSpec> {
        match self {
            InstrumentSpec::Scalpel(s) => Some(s),
            _ => None,
        }
    }

    /// The driver and its needle, for a needle driver.
    pub fn needle_driver(&self) -> Option<&super::suture::NeedleDriverSpec> {
        match self {
            InstrumentSpec::NeedleDriver(n) => Some(n),
            _ => None,
        }
    }

    /// The blades, for scissors.
    pub fn scissors(&self) -> Option<&ScissorsSpec> {
        match self {
            InstrumentSpec::Scissors(s) => Some(s),
            _ => None,
        }
    }
}

/// A scalpel's blade: a sharp edge, a segment in the tool frame. Between two ticks the edge sweeps a surface;
/// tissue it sweeps through is cut along the mesh's facets (`interaction::cut`). The edge does not push
/// tissue (it passes through it); the tool's `shape` is the blunt back and probes as any body does. The drag
/// felt while cutting is the tissue's (its material's `cut_resistance_n`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalpelSpec {
    /// The edge's two ends in the tool frame, mm.
    pub edge_mm: [[f32; 3]; 2],
}

impl ScalpelSpec {
    /// Defaults of `kind = "scalpel"`: an 8 mm edge from 1 mm to 9 mm below the tool origin along its local
    /// -z (below a small blunt back at the origin).
    pub const DEFAULT: ScalpelSpec = ScalpelSpec {
        edge_mm: [[0.0, 0.0, -1.0], [0.0, 0.0, -9.0]],
    };
}

/// A pair of scissors: two straight blades hinged about the tool's local x axis at `hinge_mm`, each running
/// `blade_length_mm` along the tool's -z and turned by half the jaw opening to either side (+y, -y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScissorsSpec {
    /// What opens and closes the blades.
    pub activation: JawActivation,
    /// Opening of the open blades, rad.
    pub open_angle_rad: f32,
    /// Length of each blade from the hinge, mm.
    pub blade_length_mm: f32,
    /// The hinge in the tool frame, mm.
    pub hinge_mm: [f32; 3],
}

impl ScissorsSpec {
    /// Defaults of `kind = "scissors"`: a button closes two 12 mm blades opened 40 degrees, hinged at the tool
    /// origin.
    pub const DEFAULT: ScissorsSpec = ScissorsSpec {
        activation: JawActivation::Button { mask: 1 },
        open_angle_rad: 40.0 * std::f32::consts::PI / 180.0,
        blade_length_mm: 12.0,
        hinge_mm: [0.0, 0.0, 0.0],
    };

    /// How far each closed blade has passed the other's line, rad (3 degrees): scissors' blades shear past
    /// each other, so tissue between them is cut by the time they close.
    pub const CROSSING_RAD: f32 = 3.0 * std::f32::consts::PI / 180.0;

    /// Blades cut from this far out from the hinge, mm (the crotch itself does not cut).
    pub const CROTCH_MM: f32 = 0.2;

    /// The two blades' ends (crotch, tip) in the tool frame at jaw opening `jaw_angle_rad`, mm: the +y blade
    /// first.
    pub fn blades_mm(&self, jaw_angle_rad: f32) -> [[[f32; 3]; 2]; 2] {
        let half = 0.5 * jaw_angle_rad.clamp(0.0, self.open_angle_rad) - Self::CROSSING_RAD;
        let (sin, cos) = half.sin_cos();
        let h = self.hinge_mm;
        let blade = |sign: f32| {
            let at = |r: f32| [h[0], h[1] + sign * r * sin, h[2] - r * cos];
            [at(Self::CROTCH_MM), at(self.blade_length_mm)]
        };
        [blade(1.0), blade(-1.0)]
    }
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

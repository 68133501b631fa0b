//! A tool as drawable primitives in the world frame: its shape (ball, capsule or mesh), a grasper's or needle
//! driver's jaws and scissors' blades opened by the jaw angle, a scalpel's edge, a needle's arc and the shaft.
//!
//! Owns: [`tool_parts`], the instrument geometry every drawing of a tool shares (where the jaws hinge and how
//! they open, where the edge and the needle lie in the tool frame), and the tool colours by state. The kiss3d
//! scene places its nodes with the same segments ([`jaw_segments_in_tool`], [`edge_segments_in_tool`]); the
//! browser feed sends the parts as they are.
//!
//! Must not: touch a GPU, zenoh or clocks. Plain data in, plain data out.

use kiss3d::glamx::{Quat, Vec3};
use sinew_protocol::{InstrumentInfo, NeedleState, ToolInfo, ToolShape, ToolState};

/// Colour, linear RGB 0-1 (as the kiss3d scene uses it).
pub type Rgb = [f32; 3];

/// Tool, free.
pub const TOOL_STEEL_RGB: Rgb = [0.62, 0.65, 0.70];
/// A sharp edge or a needle: bright steel, so it stands out against the blunt back.
pub const BLADE_STEEL_RGB: Rgb = [0.90, 0.92, 0.95];
/// Tool touching tissue or holding it.
pub const TOOL_CONTACT_RGB: Rgb = [0.90, 0.22, 0.16];
/// Tool with no device bound.
pub const TOOL_INACTIVE_RGB: Rgb = [0.30, 0.31, 0.34];

/// A scalpel's edge as drawn, radius mm.
pub const EDGE_RADIUS_MM: f32 = 0.25;
/// A grasper's or needle driver's jaw as drawn, radius mm.
pub const JAW_RADIUS_MM: f32 = 0.8;
/// A scissors blade as drawn, radius mm.
pub const BLADE_RADIUS_MM: f32 = 0.3;
/// Straight pieces a needle's arc is drawn in.
pub const NEEDLE_PIECES: usize = 12;

/// One straight piece in the tool frame: from, to (mm) and radius (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// One end, mm.
    pub from_mm: Vec3,
    /// The other end, mm.
    pub to_mm: Vec3,
    /// Radius, mm.
    pub radius_mm: f32,
}

/// A drawable primitive, world frame, mm.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolPart {
    /// A ball.
    Sphere {
        /// Centre, mm.
        centre_mm: [f32; 3],
        /// Radius, mm.
        radius_mm: f32,
        /// Colour.
        rgb: Rgb,
    },
    /// A capsule (a segment swept by a ball).
    Capsule {
        /// One end of the segment, mm.
        from_mm: [f32; 3],
        /// The other end, mm.
        to_mm: [f32; 3],
        /// Radius, mm.
        radius_mm: f32,
        /// Colour.
        rgb: Rgb,
    },
    /// A rigid triangle mesh.
    Mesh {
        /// Vertices, mm.
        positions_mm: Vec<[f32; 3]>,
        /// Triangles (vertex indices).
        triangles: Vec<[u32; 3]>,
        /// Colour.
        rgb: Rgb,
    },
}

/// The colour of a tool's body by its state: inactive, touching or holding, free.
pub fn body_rgb(state: &ToolState) -> Rgb {
    if !state.active {
        TOOL_INACTIVE_RGB
    } else if state.in_contact || state.attachments > 0 {
        TOOL_CONTACT_RGB
    } else {
        TOOL_STEEL_RGB
    }
}

/// World from tool for a state (the quaternion normalised; identity if it is degenerate).
pub fn world_from_tool(state: &ToolState) -> Quat {
    let [x, y, z, w] = state.orientation_xyzw;
    let q = Quat::from_xyzw(x, y, z, w);
    if q.length_squared().is_finite() && q.length_squared() > 1e-12 {
        q.normalize()
    } else {
        Quat::IDENTITY
    }
}

/// A grasper's or needle driver's jaws, or scissors' blades, opened by `jaw_angle_rad`: two segments hinged
/// about the tool's local x axis, each running along -z turned by +-half the angle, and whether they keep blade
/// steel (scissors) rather than the body's colour. None for other instruments.
pub fn jaw_segments_in_tool(info: &ToolInfo, jaw_angle_rad: f32) -> Option<([Segment; 2], bool)> {
    let (hinge_mm, length_mm, radius_mm, steel) = match info.instrument {
        InstrumentInfo::Grasper { jaw_length_mm, .. } => (
            Vec3::new(0.0, 0.0, info.shape.bounding_radius_mm()),
            jaw_length_mm,
            JAW_RADIUS_MM,
            false,
        ),
        // Meeting at the tool origin, where they hold the needle.
        InstrumentInfo::NeedleDriver { jaw_length_mm, .. } => (
            Vec3::new(0.0, 0.0, jaw_length_mm),
            jaw_length_mm,
            JAW_RADIUS_MM,
            false,
        ),
        InstrumentInfo::Scissors {
            hinge_mm,
            blade_length_mm,
            ..
        } => (Vec3::from(hinge_mm), blade_length_mm, BLADE_RADIUS_MM, true),
        _ => return None,
    };
    let length_mm = if length_mm.is_finite() {
        length_mm.max(0.1)
    } else {
        0.1
    };
    let half = 0.5
        * if jaw_angle_rad.is_finite() {
            jaw_angle_rad.clamp(0.0, std::f32::consts::PI)
        } else {
            0.0
        };
    let jaw = |sign: f32| Segment {
        from_mm: hinge_mm,
        to_mm: hinge_mm + Quat::from_rotation_x(sign * half) * Vec3::new(0.0, 0.0, -length_mm),
        radius_mm,
    };
    Some(([jaw(1.0), jaw(-1.0)], steel))
}

/// The sharp and fine parts, tool frame: a scalpel's edge, or a needle's arc in [`NEEDLE_PIECES`] pieces
/// (placed by the protocol's own map); empty for other instruments.
pub fn edge_segments_in_tool(info: &ToolInfo) -> Vec<Segment> {
    match info.instrument {
        InstrumentInfo::Scalpel {
            edge_from_mm,
            edge_to_mm,
        } => vec![Segment {
            from_mm: Vec3::from(edge_from_mm),
            to_mm: Vec3::from(edge_to_mm),
            radius_mm: EDGE_RADIUS_MM,
        }],
        InstrumentInfo::NeedleDriver {
            needle_radius_mm,
            needle_sweep_rad,
            needle_diameter_mm,
            grasp_at_rad,
            ..
        } => {
            let at = |k: usize| {
                let theta = needle_sweep_rad * k as f32 / NEEDLE_PIECES as f32;
                Vec3::from(sinew_protocol::needle_point_in_tool_mm(
                    needle_radius_mm,
                    grasp_at_rad,
                    theta,
                ))
            };
            (0..NEEDLE_PIECES)
                .map(|k| Segment {
                    from_mm: at(k),
                    to_mm: at(k + 1),
                    radius_mm: 0.5 * needle_diameter_mm,
                })
                .collect()
        }
        _ => Vec::new(),
    }
}

/// An instrument's shaft, tool frame: from the origin up the local z.
pub fn shaft_segment_in_tool(info: &ToolInfo) -> Option<Segment> {
    let shaft = info.shaft?;
    Some(Segment {
        from_mm: Vec3::ZERO,
        to_mm: Vec3::new(0.0, 0.0, shaft.length_mm),
        radius_mm: shaft.radius_mm,
    })
}

/// Where a needle driver's needle lies: its own pose when the server sends one (protocol 15: a needle let go
/// or handed over), else its driver's. The other fields are the driver's state.
pub fn needle_pose(state: &ToolState, needles: &[NeedleState]) -> ToolState {
    needles
        .iter()
        .find(|n| n.tool == state.tool)
        .map_or(*state, |n| ToolState {
            position_mm: n.position_mm,
            orientation_xyzw: n.orientation_xyzw,
            ..*state
        })
}

/// A segment in some frame as a world-frame capsule (`world` maps the frame's points), or None if it is
/// degenerate (zero or non-finite length or radius).
fn capsule_part(
    segment: &Segment,
    world: &impl Fn(Vec3) -> [f32; 3],
    rgb: Rgb,
) -> Option<ToolPart> {
    let length = (segment.to_mm - segment.from_mm).length();
    if !(length.is_finite()
        && length > 0.0
        && segment.radius_mm.is_finite()
        && segment.radius_mm > 0.0)
    {
        return None;
    }
    Some(ToolPart::Capsule {
        from_mm: world(segment.from_mm),
        to_mm: world(segment.to_mm),
        radius_mm: segment.radius_mm,
        rgb,
    })
}

/// Every part of one tool at `state` (its needle, if it has one, where `needles` puts it), world frame. An inactive tool is drawn too (greyed), where it was left.
/// Degenerate pieces (zero or non-finite length or radius) are left out.
pub fn tool_parts(info: &ToolInfo, state: &ToolState, needles: &[NeedleState]) -> Vec<ToolPart> {
    let rotation = world_from_tool(state);
    let origin = Vec3::from(state.position_mm);
    let world = |p: Vec3| (origin + rotation * p).to_array();
    let body = body_rgb(state);
    let mut parts = Vec::new();
    let capsule = |segment: &Segment, rgb: Rgb| capsule_part(segment, &world, rgb);
    match &info.shape {
        ToolShape::Sphere { radius_mm } => parts.push(ToolPart::Sphere {
            centre_mm: origin.to_array(),
            radius_mm: radius_mm.max(0.1),
            rgb: body,
        }),
        ToolShape::Capsule {
            half_length_mm,
            radius_mm,
        } => {
            let axis = Segment {
                from_mm: Vec3::new(0.0, 0.0, -half_length_mm),
                to_mm: Vec3::new(0.0, 0.0, *half_length_mm),
                radius_mm: radius_mm.max(0.1),
            };
            parts.extend(capsule(&axis, body).or(Some(ToolPart::Sphere {
                centre_mm: origin.to_array(),
                radius_mm: radius_mm.max(0.1),
                rgb: body,
            })));
        }
        ToolShape::Mesh {
            positions_mm,
            triangles,
        } => parts.push(ToolPart::Mesh {
            positions_mm: positions_mm.iter().map(|p| world(Vec3::from(*p))).collect(),
            triangles: triangles.clone(),
            rgb: body,
        }),
    }
    if let Some((jaws, steel)) = jaw_segments_in_tool(info, state.jaw_angle_rad) {
        let rgb = if steel { BLADE_STEEL_RGB } else { body };
        parts.extend(jaws.iter().filter_map(|jaw| capsule(jaw, rgb)));
    }
    let edges = edge_segments_in_tool(info);
    if matches!(info.instrument, InstrumentInfo::NeedleDriver { .. }) {
        let needle = needle_pose(state, needles);
        let rotation = world_from_tool(&needle);
        let origin = Vec3::from(needle.position_mm);
        let world = |p: Vec3| (origin + rotation * p).to_array();
        parts.extend(
            edges
                .iter()
                .filter_map(|edge| capsule_part(edge, &world, BLADE_STEEL_RGB)),
        );
    } else {
        parts.extend(
            edges
                .iter()
                .filter_map(|edge| capsule(edge, BLADE_STEEL_RGB)),
        );
    }
    if let Some(shaft) = shaft_segment_in_tool(info) {
        parts.extend(capsule(&shaft, TOOL_STEEL_RGB));
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use sinew_protocol::ToolShaft;

    fn state(jaw_angle_rad: f32) -> ToolState {
        ToolState {
            tool: 0,
            position_mm: [10.0, 0.0, 5.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            force_n: [0.0; 3],
            active: true,
            in_contact: false,
            jaw_angle_rad,
            attachments: 0,
        }
    }

    fn grasper() -> ToolInfo {
        ToolInfo {
            tool: 0,
            name: "grasper".into(),
            device_id: "right".into(),
            shape: ToolShape::Sphere { radius_mm: 2.0 },
            instrument: InstrumentInfo::Grasper {
                jaw_length_mm: 8.0,
                open_angle_rad: 0.6,
            },
            shaft: Some(ToolShaft {
                radius_mm: 1.5,
                length_mm: 60.0,
            }),
        }
    }

    #[test]
    fn a_grasper_is_a_ball_two_jaws_that_open_with_the_angle_and_a_shaft_upwards() {
        let parts = tool_parts(&grasper(), &state(0.6), &[]);
        assert_eq!(parts.len(), 4, "{parts:?}");
        assert!(matches!(
            parts[0],
            ToolPart::Sphere {
                centre_mm: [10.0, 0.0, 5.0],
                ..
            }
        ));
        let tip = |p: &ToolPart| match p {
            ToolPart::Capsule { to_mm, .. } => *to_mm,
            other => panic!("{other:?}"),
        };
        let (a, b) = (tip(&parts[1]), tip(&parts[2]));
        // Both jaws hang down from the hinge 2 mm above the origin, and spread in y by 2 * 8 sin(0.3).
        assert!(a[2] < 5.0 && b[2] < 5.0);
        assert!(((a[1] - b[1]).abs() - 2.0 * 8.0 * 0.3f32.sin()).abs() < 1e-4);
        match &parts[3] {
            ToolPart::Capsule {
                from_mm,
                to_mm,
                radius_mm,
                ..
            } => {
                assert_eq!(*from_mm, [10.0, 0.0, 5.0]);
                assert_eq!(*to_mm, [10.0, 0.0, 65.0]);
                assert_eq!(*radius_mm, 1.5);
            }
            other => panic!("{other:?}"),
        }
        let closed = tool_parts(&grasper(), &state(0.0), &[]);
        assert_eq!(tip(&closed[1]), tip(&closed[2]));
    }

    #[test]
    fn a_bad_orientation_or_jaw_angle_draws_the_tool_upright_and_closed() {
        let mut s = state(f32::NAN);
        s.orientation_xyzw = [0.0; 4];
        let parts = tool_parts(&grasper(), &s, &[]);
        assert_eq!(parts.len(), 4);
        for part in &parts {
            if let ToolPart::Capsule { from_mm, to_mm, .. } = part {
                assert!(
                    from_mm.iter().chain(to_mm).all(|c| c.is_finite()),
                    "{part:?}"
                );
            }
        }
    }

    #[test]
    fn a_scalpel_shows_its_edge_in_blade_steel_and_an_idle_tool_is_grey() {
        let info = ToolInfo {
            instrument: InstrumentInfo::Scalpel {
                edge_from_mm: [0.0, 0.0, -1.0],
                edge_to_mm: [0.0, 10.0, -1.0],
            },
            shaft: None,
            ..grasper()
        };
        let mut idle = state(0.0);
        idle.active = false;
        let parts = tool_parts(&info, &idle, &[]);
        assert_eq!(parts.len(), 2);
        assert!(matches!(
            parts[0],
            ToolPart::Sphere {
                rgb: TOOL_INACTIVE_RGB,
                ..
            }
        ));
        assert!(matches!(
            parts[1],
            ToolPart::Capsule {
                from_mm: [10.0, 0.0, 4.0],
                to_mm: [10.0, 10.0, 4.0],
                rgb: BLADE_STEEL_RGB,
                ..
            }
        ));
    }
}

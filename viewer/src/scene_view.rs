//! kiss3d scene nodes mirroring a [`SceneReplica`]: one mesh per object, one sphere or capsule per tool, the
//! suture threads (in [`crate::thread_view`]) and their needles' punctures (in [`crate::hole_view`]).
//!
//! Owns: the look of the scene (colours, materials, lights, background) and keeping the nodes in step with the
//! replica: new vertex positions are written into the existing GPU meshes (and normals recomputed) when only
//! positions moved; the nodes are rebuilt when the layout changed (another snapshot with other objects).
//!
//! Must not: create windows or surfaces, or be used from more than one thread. kiss3d keeps its GPU context and
//! resource managers in thread-locals: the window or offscreen surface must exist, on the calling thread, before
//! [`SceneView::sync`] creates the first node.

use kiss3d::camera::OrbitCamera3d;
use kiss3d::color::Color;
use kiss3d::glamx::{Quat, Vec3};
use kiss3d::light::Light;
use kiss3d::post_processing::Tonemap;
use kiss3d::scene::SceneNode3d;
use kiss3d::window::Window;
use sinew_protocol::{ToolInfo, ToolShape, ToolState};

use crate::camera_framing::{CameraFraming, FIELD_OF_VIEW_RAD};
use crate::hole_view::HoleView;
use crate::replica::{ReplicaObject, SceneReplica};
use crate::thread_view::ThreadView;

/// Background, 8-bit RGB as it appears in the rendered image.
pub const BACKGROUND_RGB: [u8; 3] = [28, 31, 38];
/// Soft-tissue pink.
const TISSUE: Color = Color::new(0.92, 0.46, 0.50, 1.0);
/// Tool, free.
const TOOL_STEEL: Color = Color::new(0.62, 0.65, 0.70, 1.0);
/// A scalpel's edge: bright steel, so it stands out against the blunt back.
const BLADE_STEEL: Color = Color::new(0.90, 0.92, 0.95, 1.0);
/// Tool touching tissue.
const TOOL_CONTACT: Color = Color::new(0.90, 0.22, 0.16, 1.0);
/// Ambient light level (kiss3d default 0.2).
const AMBIENT: f32 = 0.15;
/// Key light intensity (kiss3d default 3.0 saturates the pale tissue colour).
const KEY_LIGHT_INTENSITY: f32 = 1.5;
/// Fill light intensity.
const FILL_LIGHT_INTENSITY: f32 = 0.35;
/// Tool with no device bound.
const TOOL_INACTIVE: Color = Color::new(0.30, 0.31, 0.34, 1.0);

/// Background as a kiss3d clear colour. kiss3d clears its linear HDR film with it and encodes the film with
/// gamma 2.2 on output (`tonemap_ops.wgsl`), so the value is linearised here to come out as [`BACKGROUND_RGB`].
pub fn background_color() -> Color {
    let [r, g, b] = BACKGROUND_RGB.map(|c| (f32::from(c) / 255.0).powf(2.2));
    Color::new(r, g, b, 1.0)
}

/// Background, ambient light, tonemapping and shadows for a window or offscreen surface (the same `Window`
/// type underneath). No tonemapping curve: the lights are set so nothing saturates, and the background comes
/// out exactly as [`BACKGROUND_RGB`].
pub fn configure_window(window: &mut Window) {
    window.set_background_color(background_color());
    window.set_ambient(AMBIENT);
    window.set_tonemap(Tonemap::None);
    window.set_bloom_enabled(false);
    window.set_shadows_enabled(false);
}

/// Add the scene's lights (kiss3d has none by default): a key light from above-front-left and a weaker fill
/// from the other side, both directional so millimetre distances do not matter.
pub fn add_lights(scene: &mut SceneNode3d) {
    scene.add_light(
        Light::directional(Vec3::new(0.6, 0.5, -0.6))
            .with_intensity(KEY_LIGHT_INTENSITY)
            .with_casts_shadows(false),
    );
    scene.add_light(
        Light::directional(Vec3::new(-0.5, -0.2, -0.6))
            .with_intensity(FILL_LIGHT_INTENSITY)
            .with_casts_shadows(false),
    );
}

/// An orbit camera placed by `framing`, z up.
pub fn make_camera(framing: &CameraFraming) -> OrbitCamera3d {
    let mut camera = OrbitCamera3d::new_with_frustum(
        FIELD_OF_VIEW_RAD,
        framing.znear_mm,
        framing.zfar_mm,
        Vec3::from(framing.eye_mm),
        Vec3::from(framing.target_mm),
    );
    camera.set_up_axis(Vec3::Z);
    camera.look_at(Vec3::from(framing.eye_mm), Vec3::from(framing.target_mm));
    camera
}

/// What a set of nodes was built for; a change means rebuild instead of update.
#[derive(Debug, Clone, PartialEq)]
struct Layout {
    objects: Vec<(String, usize, Vec<[u32; 3]>)>,
    tools: Vec<ToolInfo>,
}

impl Layout {
    fn of(replica: &SceneReplica) -> Self {
        Self {
            objects: replica
                .objects()
                .iter()
                .map(|o| {
                    (
                        o.name().to_owned(),
                        o.vertex_count(),
                        o.triangles().to_vec(),
                    )
                })
                .collect(),
            tools: replica.tools().to_vec(),
        }
    }

    fn matches(&self, replica: &SceneReplica) -> bool {
        self.objects.len() == replica.objects().len()
            && self.tools == replica.tools()
            && self
                .objects
                .iter()
                .zip(replica.objects())
                .all(|((name, count, triangles), o)| {
                    name == o.name() && *count == o.vertex_count() && triangles == o.triangles()
                })
    }
}

struct ToolNode {
    tool: u16,
    node: SceneNode3d,
    /// Rotation from the node's own frame to the tool frame (kiss3d capsules run along y, Sinew's along z).
    tool_from_node: Quat,
    /// A grasper's two jaws, and where they hinge (tool frame, mm) and how long they are.
    jaws: Option<Jaws>,
    /// A scalpel's edge.
    blade: Option<Blade>,
    /// An instrument's shaft.
    shaft: Option<Blade>,
    /// A needle driver's needle, as straight pieces along its arc (empty for other tools).
    needle: Vec<Blade>,
}

/// A scalpel's edge or an instrument's shaft as drawn: a capsule from one point to another, in the tool frame.
struct Blade {
    node: SceneNode3d,
    /// Middle of the edge, tool frame, mm.
    centre_mm: Vec3,
    /// Rotation from the capsule's own axis (kiss3d's y) to the edge, tool frame.
    tool_from_node: Quat,
}

impl Blade {
    /// Edge radius as drawn, mm.
    const RADIUS_MM: f32 = 0.25;

    /// A scalpel's edge.
    fn add(group: &mut SceneNode3d, info: &ToolInfo) -> Option<Self> {
        let sinew_protocol::InstrumentInfo::Scalpel {
            edge_from_mm,
            edge_to_mm,
        } = info.instrument
        else {
            return None;
        };
        Self::rod(
            group,
            Vec3::from(edge_from_mm),
            Vec3::from(edge_to_mm),
            Self::RADIUS_MM,
            BLADE_STEEL,
        )
    }

    /// Pieces a needle's arc is drawn in.
    const NEEDLE_PIECES: usize = 12;

    /// A needle driver's needle: its arc in pieces, placed in the tool frame by the protocol's own map.
    fn needle(group: &mut SceneNode3d, info: &ToolInfo) -> Vec<Self> {
        let sinew_protocol::InstrumentInfo::NeedleDriver {
            needle_radius_mm,
            needle_sweep_rad,
            needle_diameter_mm,
            grasp_at_rad,
            ..
        } = info.instrument
        else {
            return Vec::new();
        };
        let at = |k: usize| {
            let theta = needle_sweep_rad * k as f32 / Self::NEEDLE_PIECES as f32;
            Vec3::from(sinew_protocol::needle_point_in_tool_mm(
                needle_radius_mm,
                grasp_at_rad,
                theta,
            ))
        };
        (0..Self::NEEDLE_PIECES)
            .filter_map(|k| {
                Self::rod(
                    group,
                    at(k),
                    at(k + 1),
                    0.5 * needle_diameter_mm,
                    BLADE_STEEL,
                )
            })
            .collect()
    }

    /// An instrument's shaft: from the tool origin up its local z.
    fn shaft(group: &mut SceneNode3d, info: &ToolInfo) -> Option<Self> {
        let shaft = info.shaft?;
        Self::rod(
            group,
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, shaft.length_mm),
            shaft.radius_mm,
            TOOL_STEEL,
        )
    }

    fn rod(
        group: &mut SceneNode3d,
        from: Vec3,
        to: Vec3,
        radius_mm: f32,
        colour: Color,
    ) -> Option<Self> {
        let along = to - from;
        let length_mm = along.length();
        if !length_mm.is_finite() || length_mm <= 0.0 || radius_mm.is_nan() || radius_mm <= 0.0 {
            return None;
        }
        let node = group
            .add_capsule(radius_mm, length_mm)
            .set_color(colour)
            .set_metallic(0.8)
            .set_roughness(0.2)
            .set_visible(false);
        Some(Self {
            node,
            centre_mm: 0.5 * (from + to),
            tool_from_node: Quat::from_rotation_arc(Vec3::Y, along / length_mm),
        })
    }

    /// Place the edge on a tool at `state` (world from tool).
    fn place(&mut self, state: &ToolState) {
        let [x, y, z, w] = state.orientation_xyzw;
        let world_from_tool = Quat::from_xyzw(x, y, z, w).normalize();
        self.node
            .set_position(Vec3::from(state.position_mm) + world_from_tool * self.centre_mm)
            .set_rotation(world_from_tool * self.tool_from_node)
            .set_visible(true);
    }

    fn hide(&mut self) {
        self.node.set_visible(false);
    }
}

/// A grasper's jaws or scissors' blades as drawn: two capsules hinged about the tool's local x axis at
/// `hinge_mm`, each running `length_mm` along the tool's -z, opened by +-half the jaw angle.
struct Jaws {
    nodes: [SceneNode3d; 2],
    hinge_mm: Vec3,
    length_mm: f32,
    /// Blades keep their steel; a grasper's jaws take the tool's colour.
    colour: Option<Color>,
}

impl Jaws {
    /// Jaw radius as drawn, mm.
    const RADIUS_MM: f32 = 0.8;
    /// Blade radius as drawn, mm.
    const BLADE_RADIUS_MM: f32 = 0.3;

    fn add(group: &mut SceneNode3d, info: &ToolInfo) -> Option<Self> {
        let (hinge_mm, length_mm, radius_mm, colour) = match info.instrument {
            sinew_protocol::InstrumentInfo::Grasper { jaw_length_mm, .. } => (
                Vec3::new(0.0, 0.0, info.shape.bounding_radius_mm()),
                jaw_length_mm,
                Self::RADIUS_MM,
                None,
            ),
            // Meeting at the tool origin, where they hold the needle (they open as its ratchet is let go).
            sinew_protocol::InstrumentInfo::NeedleDriver { jaw_length_mm, .. } => (
                Vec3::new(0.0, 0.0, jaw_length_mm),
                jaw_length_mm,
                Self::RADIUS_MM,
                None,
            ),
            sinew_protocol::InstrumentInfo::Scissors {
                hinge_mm,
                blade_length_mm,
                ..
            } => (
                Vec3::from(hinge_mm),
                blade_length_mm,
                Self::BLADE_RADIUS_MM,
                Some(BLADE_STEEL),
            ),
            _ => return None,
        };
        let length_mm = length_mm.max(0.1);
        let jaw = |group: &mut SceneNode3d| {
            group
                .add_capsule(radius_mm, length_mm)
                .set_color(colour.unwrap_or(TOOL_STEEL))
                .set_metallic(0.5)
                .set_roughness(0.35)
                .set_visible(false)
        };
        Some(Self {
            nodes: [jaw(group), jaw(group)],
            hinge_mm,
            length_mm,
            colour,
        })
    }

    /// Place both jaws on a tool at `state` (world from tool), open by `state.jaw_angle_rad`.
    fn place(&mut self, state: &ToolState, colour: Color) {
        let [x, y, z, w] = state.orientation_xyzw;
        let world_from_tool = Quat::from_xyzw(x, y, z, w).normalize();
        let half = 0.5 * state.jaw_angle_rad.clamp(0.0, std::f32::consts::PI);
        for (node, sign) in self.nodes.iter_mut().zip([1.0f32, -1.0]) {
            let tool_from_jaw = Quat::from_rotation_x(sign * half);
            let centre_tool =
                self.hinge_mm + tool_from_jaw * Vec3::new(0.0, 0.0, -0.5 * self.length_mm);
            node.set_position(Vec3::from(state.position_mm) + world_from_tool * centre_tool)
                .set_rotation(
                    world_from_tool
                        * tool_from_jaw
                        * Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
                )
                .set_color(self.colour.unwrap_or(colour))
                .set_visible(true);
        }
    }

    fn hide(&mut self) {
        for node in &mut self.nodes {
            node.set_visible(false);
        }
    }
}

/// The kiss3d nodes of one replica.
pub struct SceneView {
    group: Option<SceneNode3d>,
    objects: Vec<Option<SceneNode3d>>,
    tools: Vec<ToolNode>,
    layout: Option<Layout>,
    revision: Option<u64>,
    snapshot_revision: Option<u64>,
    object_frames: Vec<u64>,
    scratch: Vec<Vec3>,
    /// Per object, the burnt triangles drawn over its mesh (None while nothing is burnt).
    burns: Vec<Option<SceneNode3d>>,
    /// The suture threads.
    threads: ThreadView,
    /// The punctures of the threads' needles.
    holes: HoleView,
}

impl Default for SceneView {
    fn default() -> Self {
        Self::new()
    }
}

/// What a [`SceneView`] currently draws.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SceneViewCounts {
    /// Object meshes.
    pub objects: usize,
    /// Triangles over all object meshes.
    pub triangles: usize,
    /// Tool nodes.
    pub tools: usize,
    /// Thread segments, over all threads.
    pub thread_segments: usize,
    /// Holes marked, over all threads.
    pub holes: usize,
}

impl SceneView {
    /// No nodes yet.
    pub fn new() -> Self {
        Self {
            group: None,
            objects: Vec::new(),
            tools: Vec::new(),
            layout: None,
            revision: None,
            snapshot_revision: None,
            object_frames: Vec::new(),
            scratch: Vec::new(),
            burns: Vec::new(),
            threads: ThreadView::default(),
            holes: HoleView::default(),
        }
    }

    /// Bring the nodes under `scene` in step with `replica`. Cheap when the replica's revision did not move.
    /// Returns whether the nodes were rebuilt (the caller may want to re-frame the camera).
    pub fn sync(&mut self, scene: &mut SceneNode3d, replica: &SceneReplica) -> bool {
        if self.revision == Some(replica.revision()) && self.layout.is_some() {
            return false;
        }
        let rebuild = !self.layout.as_ref().is_some_and(|l| l.matches(replica));
        if rebuild {
            self.build(scene, replica);
        } else {
            self.update(replica);
        }
        self.revision = Some(replica.revision());
        self.snapshot_revision = Some(replica.snapshot_revision());
        self.object_frames = replica.objects().iter().map(ReplicaObject::frame).collect();
        rebuild
    }

    /// Forget which replica state the nodes show, so the next [`Self::sync`] writes every position and tool
    /// (the layout is kept). For drawing a different replica object, whose revision counter is its own.
    pub fn invalidate(&mut self) {
        self.revision = None;
        self.snapshot_revision = None;
    }

    /// What is drawn.
    pub fn counts(&self) -> SceneViewCounts {
        let layout = self.layout.as_ref();
        SceneViewCounts {
            objects: self.objects.iter().flatten().count(),
            triangles: layout.map_or(0, |l| l.objects.iter().map(|o| o.2.len()).sum()),
            tools: self.tools.len(),
            thread_segments: self.threads.segments(),
            holes: self.holes.shown(),
        }
    }

    fn build(&mut self, scene: &mut SceneNode3d, replica: &SceneReplica) {
        if let Some(mut old) = self.group.take() {
            old.remove();
        }
        // Their nodes went with the group.
        self.threads = ThreadView::default();
        self.holes = HoleView::default();
        let mut group = scene.add_group();
        self.objects = replica
            .objects()
            .iter()
            .map(|object| add_object_mesh(&mut group, object))
            .collect();
        self.tools = replica
            .tools()
            .iter()
            .map(|info| ToolNode {
                tool: info.tool,
                node: add_tool_shape(&mut group, info),
                jaws: Jaws::add(&mut group, info),
                blade: Blade::add(&mut group, info),
                shaft: Blade::shaft(&mut group, info),
                needle: Blade::needle(&mut group, info),
                tool_from_node: match info.shape {
                    ToolShape::Capsule { .. } => Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
                    ToolShape::Sphere { .. } | ToolShape::Mesh { .. } => Quat::IDENTITY,
                },
            })
            .collect();
        self.burns = replica
            .objects()
            .iter()
            .map(|object| add_burn_overlay(&mut group, object))
            .collect();
        self.group = Some(group);
        self.layout = Some(Layout::of(replica));
        self.update_tools(replica);
    }

    /// Write new positions into the meshes whose object moved (all of them after a new snapshot), then place
    /// the tools. Tool-only frames touch no mesh.
    fn update(&mut self, replica: &SceneReplica) {
        let after_snapshot = self.snapshot_revision != Some(replica.snapshot_revision());
        for (index, (node, object)) in self.objects.iter_mut().zip(replica.objects()).enumerate() {
            let Some(node) = node else { continue };
            if !after_snapshot && self.object_frames.get(index) == Some(&object.frame()) {
                continue;
            }
            self.scratch.clear();
            self.scratch
                .extend(object.positions_mm_iter().map(Vec3::from));
            let positions = &self.scratch;
            node.modify_vertices(&mut |coords: &mut Vec<Vec3>| {
                if coords.len() == positions.len() {
                    coords.copy_from_slice(positions);
                }
            });
            node.recompute_normals();
            // The burnt patch follows the surface: rebuilt with the positions (a small mesh, only where burnt).
            if let (Some(slot), Some(group)) = (self.burns.get_mut(index), self.group.as_mut()) {
                if let Some(mut old) = slot.take() {
                    old.remove();
                }
                *slot = add_burn_overlay(group, object);
            }
        }
        self.update_tools(replica);
    }

    fn update_tools(&mut self, replica: &SceneReplica) {
        if let Some(group) = self.group.as_mut() {
            self.threads.sync(group, &replica.tool_states().threads);
            self.holes.sync(group, &replica.tool_states().threads);
        }
        let states = &replica.tool_states().tools;
        let needles = &replica.tool_states().needles;
        for tool in &mut self.tools {
            match states.iter().find(|s| s.tool == tool.tool) {
                Some(state) => {
                    let colour = place_tool(&mut tool.node, tool.tool_from_node, state);
                    if let Some(jaws) = &mut tool.jaws {
                        jaws.place(state, colour);
                    }
                    if let Some(blade) = &mut tool.blade {
                        blade.place(state);
                    }
                    if let Some(shaft) = &mut tool.shaft {
                        shaft.place(state);
                    }
                    // Where the needle lies, whoever holds it (its driver's pose until a server says: protocol 15).
                    let needle = needles
                        .iter()
                        .find(|n| n.tool == tool.tool)
                        .map_or(*state, |n| ToolState {
                            position_mm: n.position_mm,
                            orientation_xyzw: n.orientation_xyzw,
                            ..*state
                        });
                    for piece in &mut tool.needle {
                        piece.place(&needle);
                    }
                }
                None => {
                    tool.node.set_visible(false);
                    if let Some(jaws) = &mut tool.jaws {
                        jaws.hide();
                    }
                    if let Some(shaft) = &mut tool.shaft {
                        shaft.hide();
                    }
                    if let Some(blade) = &mut tool.blade {
                        blade.hide();
                    }
                    for piece in &mut tool.needle {
                        piece.hide();
                    }
                }
            }
        }
    }
}

/// A mesh node for `object`, or `None` for an object with nothing to draw.
fn add_object_mesh(group: &mut SceneNode3d, object: &ReplicaObject) -> Option<SceneNode3d> {
    if object.triangles().is_empty() || object.vertex_count() == 0 {
        return None;
    }
    let vertices: Vec<Vec3> = object.positions_mm_iter().map(Vec3::from).collect();
    let node = group
        .add_trimesh(vertices, object.triangles().to_vec(), Vec3::ONE, false)
        .set_color(TISSUE)
        .set_roughness(0.9)
        .set_metallic(0.0)
        .enable_backface_culling(false);
    Some(node)
}

/// Burn colours, by level: seared (yellow), cooked (brown), charred (black).
const BURN_COLOURS: [(u8, Color); 3] = [
    (1, Color::new(0.93, 0.80, 0.30, 1.0)),
    (96, Color::new(0.45, 0.27, 0.12, 1.0)),
    (192, Color::new(0.08, 0.06, 0.05, 1.0)),
];

/// The burnt triangles of `object` (a triangle takes its corners' mean level), one mesh per colour, lifted
/// 0.05 mm off the surface along each triangle's normal; None when nothing is burnt.
fn add_burn_overlay(group: &mut SceneNode3d, object: &ReplicaObject) -> Option<SceneNode3d> {
    let burn = object.burn();
    if burn.iter().all(|&b| b == 0) {
        return None;
    }
    let positions: Vec<Vec3> = object.positions_mm_iter().map(Vec3::from).collect();
    let mut overlay = group.add_group();
    for (k, &(from, colour)) in BURN_COLOURS.iter().enumerate() {
        let to = BURN_COLOURS
            .get(k + 1)
            .map_or(256, |(next, _)| u16::from(*next));
        let mut vertices = Vec::new();
        let mut faces = Vec::new();
        for t in object.triangles() {
            let corners = t.map(|v| v as usize);
            let (Some(a), Some(b), Some(c)) = (
                positions.get(corners[0]),
                positions.get(corners[1]),
                positions.get(corners[2]),
            ) else {
                continue;
            };
            let level = corners
                .iter()
                .map(|&v| u16::from(burn.get(v).copied().unwrap_or(0)))
                .sum::<u16>()
                / 3;
            if level < u16::from(from) || level >= to {
                continue;
            }
            let lift = (*b - *a).cross(*c - *a).normalize_or_zero() * 0.05;
            let first = vertices.len() as u32;
            vertices.extend([*a + lift, *b + lift, *c + lift]);
            faces.push([first, first + 1, first + 2]);
        }
        if !faces.is_empty() {
            overlay
                .add_trimesh(vertices, faces, Vec3::ONE, false)
                .set_color(colour)
                .set_roughness(0.95)
                .set_metallic(0.0)
                .enable_backface_culling(false);
        }
    }
    Some(overlay)
}

/// A sphere, capsule or mesh node for a tool.
fn add_tool_shape(group: &mut SceneNode3d, info: &ToolInfo) -> SceneNode3d {
    let mut node = match &info.shape {
        ToolShape::Sphere { radius_mm } => group.add_sphere(radius_mm.max(0.1)),
        ToolShape::Capsule {
            half_length_mm,
            radius_mm,
        } => group.add_capsule(radius_mm.max(0.1), 2.0 * half_length_mm),
        ToolShape::Mesh {
            positions_mm,
            triangles,
        } => group.add_trimesh(
            positions_mm.iter().map(|p| Vec3::from_array(*p)).collect(),
            triangles.clone(),
            Vec3::ONE,
            false,
        ),
    };
    node.set_color(TOOL_STEEL)
        .set_metallic(0.5)
        .set_roughness(0.35)
        .set_visible(false)
}

/// Place a tool's node; returns the colour it was given (inactive, grasping or touching, free).
fn place_tool(node: &mut SceneNode3d, tool_from_node: Quat, state: &ToolState) -> Color {
    let [x, y, z, w] = state.orientation_xyzw;
    let world_from_tool = Quat::from_xyzw(x, y, z, w).normalize();
    let color = if !state.active {
        TOOL_INACTIVE
    } else if state.in_contact || state.attachments > 0 {
        TOOL_CONTACT
    } else {
        TOOL_STEEL
    };
    node.set_position(Vec3::from(state.position_mm))
        .set_rotation(world_from_tool * tool_from_node)
        .set_color(color)
        .set_visible(true);
    color
}

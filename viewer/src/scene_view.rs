//! kiss3d scene nodes mirroring a [`SceneReplica`]: one mesh per object, one sphere or capsule per tool with its
//! jaws, edges and shaft (their geometry from [`crate::tool_parts`]), the
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
use crate::tool_parts::{
    BLADE_STEEL_RGB, Rgb, Segment, TOOL_STEEL_RGB, body_rgb, edge_segments_in_tool,
    jaw_segments_in_tool, needle_pose, shaft_segment_in_tool, world_from_tool,
};

/// Background, 8-bit RGB as it appears in the rendered image.
pub const BACKGROUND_RGB: [u8; 3] = [28, 31, 38];
/// Soft-tissue pink.
const TISSUE: Color = Color::new(0.92, 0.46, 0.50, 1.0);
/// Tool, free.
const TOOL_STEEL: Color = colour(TOOL_STEEL_RGB);
/// A scalpel's edge: bright steel, so it stands out against the blunt back.
const BLADE_STEEL: Color = colour(BLADE_STEEL_RGB);
/// Ambient light level (kiss3d default 0.2).
const AMBIENT: f32 = 0.15;
/// Key light intensity (kiss3d default 3.0 saturates the pale tissue colour).
const KEY_LIGHT_INTENSITY: f32 = 1.5;
/// Fill light intensity.
const FILL_LIGHT_INTENSITY: f32 = 0.35;

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
    /// A grasper's or needle driver's jaws, or scissors' blades.
    jaws: Option<Jaws>,
    /// A scalpel's edge, or a needle driver's needle as straight pieces along its arc.
    edges: Vec<Blade>,
    /// The edges are a needle's: they follow the needle's own pose when a server sends one.
    edges_are_a_needle: bool,
    /// An instrument's shaft.
    shaft: Option<Blade>,
}

/// A straight piece of a tool as drawn (an edge, a piece of needle, a shaft): a capsule placed by a
/// [`Segment`] of [`crate::tool_parts`], in the tool frame.
struct Blade {
    node: SceneNode3d,
    /// Middle of the piece, tool frame, mm.
    centre_mm: Vec3,
    /// Rotation from the capsule's own axis (kiss3d's y) to the piece, tool frame.
    tool_from_node: Quat,
}

impl Blade {
    /// A tool's sharp and fine pieces: a scalpel's edge, a needle's arc.
    fn edges(group: &mut SceneNode3d, info: &ToolInfo) -> Vec<Self> {
        edge_segments_in_tool(info)
            .iter()
            .filter_map(|segment| Self::rod(group, segment, BLADE_STEEL))
            .collect()
    }

    /// An instrument's shaft.
    fn shaft(group: &mut SceneNode3d, info: &ToolInfo) -> Option<Self> {
        Self::rod(group, &shaft_segment_in_tool(info)?, TOOL_STEEL)
    }

    fn rod(group: &mut SceneNode3d, segment: &Segment, colour: Color) -> Option<Self> {
        let along = segment.to_mm - segment.from_mm;
        let length_mm = along.length();
        let radius_mm = segment.radius_mm;
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
            centre_mm: 0.5 * (segment.from_mm + segment.to_mm),
            tool_from_node: Quat::from_rotation_arc(Vec3::Y, along / length_mm),
        })
    }

    /// Place the piece on a tool at `state` (world from tool).
    fn place(&mut self, state: &ToolState) {
        let world_from_tool = world_from_tool(state);
        self.node
            .set_position(Vec3::from(state.position_mm) + world_from_tool * self.centre_mm)
            .set_rotation(world_from_tool * self.tool_from_node)
            .set_visible(true);
    }

    fn hide(&mut self) {
        self.node.set_visible(false);
    }
}

/// A grasper's jaws or scissors' blades as drawn: two capsules laid along the segments
/// [`jaw_segments_in_tool`] gives for the state's jaw angle.
struct Jaws {
    nodes: [SceneNode3d; 2],
    info: ToolInfo,
    /// Blades keep their steel; a grasper's jaws take the tool's colour.
    colour: Option<Color>,
}

impl Jaws {
    fn add(group: &mut SceneNode3d, info: &ToolInfo) -> Option<Self> {
        let ([jaw, _], steel) = jaw_segments_in_tool(info, 0.0)?;
        let colour = steel.then_some(BLADE_STEEL);
        let length_mm = (jaw.to_mm - jaw.from_mm).length();
        let add = |group: &mut SceneNode3d| {
            group
                .add_capsule(jaw.radius_mm, length_mm)
                .set_color(colour.unwrap_or(TOOL_STEEL))
                .set_metallic(0.5)
                .set_roughness(0.35)
                .set_visible(false)
        };
        Some(Self {
            nodes: [add(group), add(group)],
            info: info.clone(),
            colour,
        })
    }

    /// Place both jaws on a tool at `state` (world from tool), open by `state.jaw_angle_rad`.
    fn place(&mut self, state: &ToolState, colour: Color) {
        let Some((segments, _)) = jaw_segments_in_tool(&self.info, state.jaw_angle_rad) else {
            return;
        };
        let world_from_tool = world_from_tool(state);
        for (node, jaw) in self.nodes.iter_mut().zip(segments) {
            let along = (jaw.to_mm - jaw.from_mm).normalize_or(Vec3::NEG_Z);
            node.set_position(
                Vec3::from(state.position_mm) + world_from_tool * (0.5 * (jaw.from_mm + jaw.to_mm)),
            )
            .set_rotation(world_from_tool * Quat::from_rotation_arc(Vec3::Y, along))
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
                edges: Blade::edges(&mut group, info),
                edges_are_a_needle: matches!(
                    info.instrument,
                    sinew_protocol::InstrumentInfo::NeedleDriver { .. }
                ),
                shaft: Blade::shaft(&mut group, info),
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
                    if let Some(shaft) = &mut tool.shaft {
                        shaft.place(state);
                    }
                    // Where the needle lies, whoever holds it (its driver's pose until a server says: protocol 15).
                    let at = if tool.edges_are_a_needle {
                        needle_pose(state, needles)
                    } else {
                        *state
                    };
                    for piece in &mut tool.edges {
                        piece.place(&at);
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
                    for piece in &mut tool.edges {
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
    let color = colour(body_rgb(state));
    node.set_position(Vec3::from(state.position_mm))
        .set_rotation(world_from_tool(state) * tool_from_node)
        .set_color(color)
        .set_visible(true);
    color
}

const fn colour(rgb: Rgb) -> Color {
    Color::new(rgb[0], rgb[1], rgb[2], 1.0)
}

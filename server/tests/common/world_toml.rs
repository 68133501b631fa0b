//! World files as text, for the tests that need the file itself: the loader's refusals (key by key, line by
//! line) and worlds written beside a generated mesh. A test that only needs a different scene loads a world
//! and edits the [`sinew_server::world::World`] value instead (`scene_edits`).
#![allow(dead_code)] // each test binary uses its own subset

use std::fmt::Write as _;

/// `[sim]` and `[collision]` written out at the loader's defaults (a 1 kHz tick, 60 Hz publishing, a 0.1 s
/// pose timeout, a 2 mm broad-phase margin).
pub const SIM_DEFAULTS: &str = "[sim]\ntick_hz = 1000\npublish_hz = 60\npose_timeout_s = 0.1\n\n[collision]\nmargin_mm = 2.0\n";

/// A world of one sheet (an OBJ surface in mm, springs along its edges) and one tool, as a world file's text.
/// Every field is TOML as the file holds it (`dt_s: "0.001"`), so a test can still find and replace a line.
#[derive(Debug, Clone)]
pub struct SheetWorldToml {
    /// `scene = "..."`.
    pub scene: String,
    /// Sections between the scene and the object (`[sim]`, `[collision]`; empty: the loader's defaults).
    pub sim: String,
    /// The object's `name`.
    pub name: String,
    /// The object's `mesh` (units are mm).
    pub mesh: String,
    /// The object's `integrator`.
    pub integrator: String,
    /// The object's `dt_s`.
    pub dt_s: String,
    /// Further keys of the object's table (`quant_margin_mm`, `region`, ...), a line each.
    pub object_keys: String,
    /// The keys of `[objects.material]`, a line each.
    pub material: String,
    /// Each `[[objects.fixed]]` table's keys ([`fixed_plane`], [`fixed_box`]).
    pub fixed: Vec<String>,
    /// The `[[tools]]` table's keys ([`sphere_tool`] and any more).
    pub tool: String,
}

impl SheetWorldToml {
    /// The world file's text.
    pub fn text(&self) -> String {
        let mut text = format!("scene = \"{}\"\n", self.scene);
        if !self.sim.is_empty() {
            write!(text, "\n{}", self.sim).unwrap();
        }
        write!(
            text,
            "\n[[objects]]\nname = \"{}\"\nmesh = \"{}\"\nunits = \"mm\"\nintegrator = \"{}\"\ndt_s = {}\n{}\n\
             [objects.material]\n{}",
            self.name, self.mesh, self.integrator, self.dt_s, self.object_keys, self.material
        )
        .unwrap();
        for fixed in &self.fixed {
            write!(text, "\n[[objects.fixed]]\n{fixed}").unwrap();
        }
        write!(text, "\n[[tools]]\n{}", self.tool).unwrap();
        text
    }
}

/// `[[objects.fixed]]` keys: the nodes on or beyond the plane through `point_mm` with `normal`, within
/// `tolerance_mm`.
pub fn fixed_plane(point_mm: [f32; 3], normal: [f32; 3], tolerance_mm: f32) -> String {
    format!(
        "kind = \"plane\"\npoint_mm = {point_mm:?}\nnormal = {normal:?}\ntolerance_mm = {tolerance_mm:?}\n"
    )
}

/// `[[objects.fixed]]` keys: the nodes inside the box.
pub fn fixed_box(min_mm: [f32; 3], max_mm: [f32; 3]) -> String {
    format!("kind = \"box\"\nmin_mm = {min_mm:?}\nmax_mm = {max_mm:?}\n")
}

/// `[[tools]]` keys: tool `name`, driven by device `device`, a sphere of `radius_mm`.
pub fn sphere_tool(name: &str, device: &str, radius_mm: f32) -> String {
    format!(
        "name = \"{name}\"\ndevice = \"{device}\"\nshape = {{ kind = \"sphere\", radius_mm = {radius_mm:?} }}\n"
    )
}

//! Interactive window: draws the live replica of a running viewer until the window closes.
//!
//! Owns: the on-screen render loop (kiss3d 0.47 `Window`, orbit camera: left-drag rotates, right-drag pans,
//! scroll zooms). Each frame it copies the replica's new positions into the GPU meshes if the replica moved,
//! and draws the instructor's overlay (participants, force arrows, live score) over the scene.
//!
//! Must not: run anywhere but the process's main thread (winit's rule on Linux), or be called without a
//! display: kiss3d panics when it cannot open a window, so the display variables are checked first and any
//! remaining panic is turned into [`ViewerError::Window`].

use std::panic::AssertUnwindSafe;

use kiss3d::scene::SceneNode3d;
use kiss3d::window::Window;

use crate::camera_framing::frame_replica;
use crate::client::ViewerHandle;
use crate::error::{ViewerError, panic_detail};
use crate::instructor_overlay::{InstructorOverlay, draw_overlay};
use crate::replica::SceneReplica;
use crate::scene_view::{SceneView, add_lights, configure_window, make_camera};

/// Whether a display server is advertised (X11 `DISPLAY` or `WAYLAND_DISPLAY`).
pub fn display_available() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|var| std::env::var_os(var).is_some_and(|v| !v.is_empty()))
}

/// Open a `width` x `height` window titled `title` and draw `viewer`'s live replica until the window closes.
/// Call from the main thread.
pub fn run_window(
    viewer: &ViewerHandle,
    title: &str,
    width: u32,
    height: u32,
) -> Result<(), ViewerError> {
    run_window_until(viewer, title, width, height, &|| false)
}

/// As [`run_window`], but also closes the window as soon as `stop()` returns true (checked every frame).
pub fn run_window_until(
    viewer: &ViewerHandle,
    title: &str,
    width: u32,
    height: u32,
    stop: &dyn Fn() -> bool,
) -> Result<(), ViewerError> {
    if !display_available() {
        return Err(ViewerError::NoDisplay);
    }
    std::panic::catch_unwind(AssertUnwindSafe(|| {
        kiss3d::pollster::block_on(window_loop(viewer, title, width, height, stop));
    }))
    .map_err(|payload| ViewerError::Window(panic_detail(payload.as_ref())))
}

async fn window_loop(
    viewer: &ViewerHandle,
    title: &str,
    width: u32,
    height: u32,
    stop: &dyn Fn() -> bool,
) {
    // The window first: it installs the thread-local GPU context the nodes below need.
    let mut window = Window::new_with_size(title, width, height).await;
    configure_window(&mut window);
    let mut scene = SceneNode3d::empty();
    add_lights(&mut scene);
    let mut view = SceneView::new();
    let mut camera = make_camera(&viewer.with_replica(frame_replica));
    let mut framed_on_objects = false;
    let mut drawn_revision = None;
    let font = kiss3d::text::Font::default();
    let mut overlay = InstructorOverlay::default();
    while window.render_3d(&mut scene, &mut camera).await {
        if stop() {
            break;
        }
        // kiss3d draws text and lines for one frame only: queue the overlay for the next one every time.
        draw_overlay(&mut window, &overlay, &font);
        // Copy the replica out only when it moved, and update the GPU meshes outside the viewer's lock so
        // the zenoh callbacks never wait on normal recomputation.
        let revision = viewer.with_replica(SceneReplica::revision);
        if drawn_revision == Some(revision) {
            continue;
        }
        let replica = viewer.replica();
        drawn_revision = Some(replica.revision());
        overlay = InstructorOverlay::build(&replica, viewer.server_stats().as_ref());
        let rebuilt = view.sync(&mut scene, &replica);
        // Frame the camera once, when the first snapshot brings objects; then the user drives it.
        if rebuilt && !replica.objects().is_empty() && !framed_on_objects {
            camera = make_camera(&frame_replica(&replica));
            framed_on_objects = true;
        }
    }
    drop(view);
    drop(scene);
    drop(window);
}

//! Offscreen rendering of a replica to an RGB image or a PNG file, with no display.
//!
//! Owns: the offscreen path (kiss3d 0.47 `OffscreenSurface`, which runs on Mesa lavapipe when no GPU exists).
//! Each call renders on its own short-lived thread `sinew-viewer-render`, because kiss3d keeps its GPU context
//! in thread-locals and panics (rather than returning an error) when no adapter exists: the thread boundary
//! turns that panic into [`ViewerError::NoGpuAdapter`] and leaves the caller's thread clean.
//!
//! Must not: open a window, talk to zenoh, or hold GPU state between calls.

use std::path::Path;
use std::time::Instant;

use image::RgbImage;
use kiss3d::scene::SceneNode3d;
use kiss3d::window::OffscreenSurface;

use crate::camera_framing::{CameraFraming, frame_replica};
use crate::error::ViewerError;
use crate::instructor_overlay::{InstructorOverlay, draw_overlay};
use crate::replica::SceneReplica;
use crate::scene_view::{BACKGROUND_RGB, SceneView, add_lights, configure_window, make_camera};

/// Largest accepted image side, pixels.
const MAX_SIDE_PX: u32 = 16384;

/// What one offscreen render drew.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderStats {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Object meshes drawn.
    pub objects: usize,
    /// Triangles drawn over all objects.
    pub triangles: usize,
    /// Tools drawn.
    pub tools: usize,
    /// Pixels that differ from the background.
    pub covered_pixels: u64,
    /// Wall time to bring the scene up to date, render and read back, milliseconds (GPU surface creation
    /// excluded).
    pub render_ms: f64,
}

/// Render `replica` offscreen into a `width` x `height` RGB image (top-left origin), the camera framed on
/// everything the replica holds ([`frame_replica`]).
pub fn render_image(
    replica: &SceneReplica,
    width: u32,
    height: u32,
) -> Result<(RgbImage, RenderStats), ViewerError> {
    render_image_framed(replica, &frame_replica(replica), width, height)
}

/// Render `replica` offscreen from a given camera placement (to compare frames from a fixed viewpoint).
pub fn render_image_framed(
    replica: &SceneReplica,
    framing: &CameraFraming,
    width: u32,
    height: u32,
) -> Result<(RgbImage, RenderStats), ViewerError> {
    let mut frames = render_sequence(&[replica], framing, width, height)?;
    frames
        .pop()
        .ok_or_else(|| ViewerError::Render("renderer returned no frame".to_owned()))
}

/// One frame to render: a replica and, if wanted, the instructor's overlay drawn over it.
#[derive(Debug, Clone, Copy)]
pub struct SceneFrame<'a> {
    /// The scene.
    pub replica: &'a SceneReplica,
    /// Text and force arrows over it.
    pub overlay: Option<&'a InstructorOverlay>,
}

/// Render successive states of one scene from a fixed viewpoint with one surface: the first frame builds the
/// meshes, later frames update their vertices in place (the interactive window's path), so a sequence is
/// cheaper than separate renders. Returns one image per replica, in order.
pub fn render_sequence(
    replicas: &[&SceneReplica],
    framing: &CameraFraming,
    width: u32,
    height: u32,
) -> Result<Vec<(RgbImage, RenderStats)>, ViewerError> {
    let frames: Vec<SceneFrame<'_>> = replicas
        .iter()
        .map(|replica| SceneFrame {
            replica,
            overlay: None,
        })
        .collect();
    render_frames(&frames, framing, width, height)
}

/// As [`render_sequence`], each frame with its overlay if it has one.
pub fn render_frames(
    frames: &[SceneFrame<'_>],
    framing: &CameraFraming,
    width: u32,
    height: u32,
) -> Result<Vec<(RgbImage, RenderStats)>, ViewerError> {
    if !(1..=MAX_SIDE_PX).contains(&width) || !(1..=MAX_SIDE_PX).contains(&height) {
        return Err(ViewerError::BadImageSize { width, height });
    }
    let name = "sinew-viewer-render";
    std::thread::scope(|scope| {
        let thread = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn_scoped(scope, || {
                render_on_this_thread(frames, framing, width, height)
            })
            .map_err(|source| ViewerError::Thread { name, source })?;
        thread.join().map_err(|payload| {
            let detail = crate::error::panic_detail(payload.as_ref());
            if detail.contains("adapter") {
                ViewerError::NoGpuAdapter { detail }
            } else {
                ViewerError::Render(detail)
            }
        })
    })
}

/// Render `replica` offscreen and write it to `path` as PNG.
pub fn render_png(
    replica: &SceneReplica,
    path: &Path,
    width: u32,
    height: u32,
) -> Result<RenderStats, ViewerError> {
    render_png_with_overlay(replica, None, path, width, height)
}

/// Render `replica` offscreen with the instructor's overlay, if given, and write it to `path` as PNG.
pub fn render_png_with_overlay(
    replica: &SceneReplica,
    overlay: Option<&InstructorOverlay>,
    path: &Path,
    width: u32,
    height: u32,
) -> Result<RenderStats, ViewerError> {
    let frame = SceneFrame { replica, overlay };
    let (image, stats) = render_frames(&[frame], &frame_replica(replica), width, height)?
        .pop()
        .ok_or_else(|| ViewerError::Render("renderer returned no frame".to_owned()))?;
    image.save(path).map_err(|source| ViewerError::Image {
        path: path.to_owned(),
        source,
    })?;
    Ok(stats)
}

/// Count pixels that differ from the background by more than a small tolerance.
pub fn covered_pixels(image: &RgbImage) -> u64 {
    image
        .pixels()
        .filter(|p| {
            p.0.iter()
                .zip(BACKGROUND_RGB)
                .any(|(&c, b)| c.abs_diff(b) > 6)
        })
        .count() as u64
}

fn render_on_this_thread(
    frames: &[SceneFrame<'_>],
    framing: &CameraFraming,
    width: u32,
    height: u32,
) -> Vec<(RgbImage, RenderStats)> {
    kiss3d::pollster::block_on(async {
        // The surface first: it installs the thread-local GPU context the nodes below need.
        let mut surface = OffscreenSurface::new(width, height).await;
        configure_window(surface.window_mut());
        let mut scene = SceneNode3d::empty();
        add_lights(&mut scene);
        let mut view = SceneView::new();
        let mut camera = make_camera(framing);
        let font = kiss3d::text::Font::default();
        let mut images = Vec::with_capacity(frames.len());
        for frame in frames {
            let started = Instant::now();
            // Each frame may be its own replica object, whose revision says nothing about the last one's.
            view.invalidate();
            view.sync(&mut scene, frame.replica);
            if let Some(overlay) = frame.overlay {
                draw_overlay(surface.window_mut(), overlay, &font);
            }
            let image = surface.render_image_3d(&mut scene, &mut camera).await;
            let counts = view.counts();
            let stats = RenderStats {
                width: image.width(),
                height: image.height(),
                objects: counts.objects,
                triangles: counts.triangles,
                tools: counts.tools,
                covered_pixels: covered_pixels(&image),
                render_ms: started.elapsed().as_secs_f64() * 1e3,
            };
            images.push((image, stats));
        }
        // Nodes before the surface: dropping the surface resets kiss3d's thread-local managers.
        drop(view);
        drop(scene);
        drop(font);
        drop(surface);
        images
    })
}

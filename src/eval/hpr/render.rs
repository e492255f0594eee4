//! The renders HPR is measured with: one frame of a cloud in an [`HprView`] read back, the
//! true visibility of a mesh's vertices from its depth buffer, and the GPU time of the HPR
//! passes in the frame loop.

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};

use crate::frame::Frame;
use crate::gpu::{Context, ContextOptions};
use crate::gpu_scene::{upload, UploadOptions};
use crate::hpr::view::HprView;
use crate::methods::MethodConfig;
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::{Cloud, Light};

/// Runs `f` on a renderer of `cloud` by `method` in `view` under the headlight, reading back
/// its frames (which also keeps every pass: the graph culls passes whose results nothing uses).
fn with_renderer<T>(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    view: &HprView,
    method: &str,
    f: impl FnOnce(&mut Renderer, &View) -> Result<T>,
) -> Result<T> {
    let config = MethodConfig::parse(method)?;
    let options = config.method.upload_options(UploadOptions::default());
    let (scene, info) = upload(ctx, cloud, &options)?;
    let mut renderer = Renderer::new(
        ctx,
        &scene,
        info,
        &config,
        view.width,
        view.height,
        RendererOptions {
            readback: true,
            ..RendererOptions::default()
        },
    )?;
    let view = View {
        camera: view.camera,
        lights: vec![Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    f(&mut renderer, &view)
}

/// One frame of `cloud` by `method` in `view`, read back.
pub(crate) fn render_once(cloud: &Cloud, view: &HprView, method: &str) -> Result<Frame> {
    let ctx = Arc::new(Context::new(&ContextOptions::from_env())?);
    let frame = with_renderer(&ctx, cloud, view, method, |renderer, view| {
        renderer
            .render(view, true)?
            .context("renderer returned no frame")
    })?;
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    Ok(frame)
}

/// The vertices of `cloud`'s mesh that its depth buffer shows in `view` (true visibility).
pub(crate) fn mesh_visibility(cloud: &Cloud, view: &HprView) -> Result<Vec<u32>> {
    let frame = render_once(cloud, view, "mesh:samples=1")?;
    // A vertex may sit up to about a sample spacing behind the rasterized surface of its
    // pixel (interpolation across a triangle); points further back are hidden.
    let tolerance = 2.0 * crate::hpr::spacing(cloud) as f32;
    Ok(crate::hpr::truth::visible_from_depth(
        &cloud.positions,
        (view.camera.view(), view.view_proj()),
        (view.width, view.height),
        &frame.depth,
        tolerance,
    ))
}

/// Milliseconds per named pass.
pub(super) type PassTimes = Vec<(String, f64)>;

/// Median GPU milliseconds of the `hpr.*` passes (and each) of `config` rendering `cloud` in
/// `view`, over `frames` frames after two warm-up frames.
pub(super) fn gpu_time(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    view: &HprView,
    config: &str,
    frames: u32,
) -> Result<(f64, PassTimes)> {
    let passes = with_renderer(ctx, cloud, view, config, |renderer, view| {
        for _ in 0..2 {
            renderer.render(view, false)?;
        }
        renderer.clear_timings();
        for _ in 0..frames.max(1) {
            renderer.render(view, false)?;
        }
        renderer.finish()?;
        Ok(renderer.timings().0)
    })?;
    // Adaptive rounds that ran no workgroups still cost their (empty) dispatch and barrier:
    // every recorded round counts.
    let hpr: PassTimes = passes
        .iter()
        .filter(|p| {
            (p.name.starts_with("hpr.") && !p.name.starts_with("hpr.points."))
                || p.name.starts_with("sort.")
        })
        .map(|p| (p.name.clone(), p.median_ms))
        .collect();
    Ok((hpr.iter().map(|p| p.1).sum(), hpr))
}

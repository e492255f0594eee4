//! The view HPR is measured in (sectors from the viewport, reconstruction edges in pixels,
//! true visibility, PNG output) and the renders it needs.

use anyhow::{bail, Context as _, Result};

use crate::gpu_scene::{upload, UploadOptions};
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::{Camera, Cloud};

/// The view HPR measures pixels in: the camera from the eye to the target and the image size.
pub struct HprView {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
}

impl HprView {
    pub fn new(
        cloud: &Cloud,
        eye: glam::Vec3,
        target: Option<glam::Vec3>,
        size: (u32, u32),
    ) -> Self {
        let (centre, r) = cloud.bounding_sphere().unwrap_or((glam::Vec3::ZERO, 1.0));
        Self {
            camera: Camera::look_at_up(cloud.up, eye, target.unwrap_or(centre), r),
            width: size.0,
            height: size.1,
        }
    }

    pub fn proj(&self) -> glam::Mat4 {
        self.camera
            .projection(self.width as f32 / self.height as f32)
    }

    pub fn view_proj(&self) -> glam::Mat4 {
        self.proj() * self.camera.view()
    }

    /// The angle of a pixel at the image centre.
    pub fn pixel_angle(&self) -> f64 {
        2.0 / (f64::from(self.proj().y_axis.y.abs()) * f64::from(self.height))
    }

    /// The pixel of `p`, `None` behind the eye.
    pub fn pixel(&self, p: glam::Vec3) -> Option<glam::Vec2> {
        let c = self.view_proj() * p.extend(1.0);
        (c.w > 0.0).then(|| {
            let ndc = c.truncate().truncate() / c.w;
            (ndc + 1.0) * 0.5 * glam::Vec2::new(self.width as f32, self.height as f32)
        })
    }
}

/// One frame of `cloud` by `method` in `view`, read back.
pub fn render_once(cloud: &Cloud, view: &HprView, method: &str) -> Result<crate::frame::Frame> {
    let ctx = std::sync::Arc::new(crate::gpu::Context::new(
        &crate::gpu::ContextOptions::from_env(),
    )?);
    let config = crate::methods::MethodConfig::parse(method)?;
    let options = config.method.upload_options(UploadOptions::default());
    let (scene, info) = upload(&ctx, cloud, &options)?;
    let mut renderer = Renderer::new(
        &ctx,
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
    let frame = renderer
        .render(
            &View {
                camera: view.camera,
                lights: vec![crate::scene::Light::headlight()],
                use_color: true,
                time: 0.0,
            },
            true,
        )?
        .context("renderer returned no frame")?;
    drop(renderer);
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    Ok(frame)
}

/// The vertices of `cloud`'s mesh that its depth buffer shows in `view` (true visibility).
pub fn mesh_visibility(cloud: &Cloud, view: &HprView) -> Result<Vec<u32>> {
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

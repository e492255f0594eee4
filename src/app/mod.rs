//! The interactive viewer: a winit window, an ash swapchain, an orbit/pan/zoom camera, keys to
//! switch methods and toggle color, and per-pass GPU milliseconds in the title.
//!
//! Controls: left drag orbits, right (or middle) drag pans, the wheel zooms, `M`/`N` switch to
//! the next/previous method, `C` toggles point colors, `V` cycles the fields to color by,
//! `R` resets the camera, `Esc` quits.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use glam::{Vec2, Vec3};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::raw_window_handle::HasDisplayHandle;
use winit::window::{Window, WindowId};

use crate::color::{self, Coloring};
use crate::gpu::swapchain::Swapchain;
use crate::gpu::{Context, ContextOptions, ImageDesc};
use crate::methods::{MethodConfig, METHODS};
use crate::render::{upload_colored, Extras, Renderer, SceneInfo, View};
use crate::scene::camera::{orbit_angles, orbit_direction};
use crate::scene::{Camera, Cloud, Light, Up};

/// What the viewer shows.
pub struct ViewerOptions {
    pub title: String,
    pub method: MethodConfig,
    pub camera: Camera,
    /// The axis the drag orbit turns about.
    pub up: Up,
    pub lights: Vec<Light>,
    /// The field colored by at start (`V` cycles `color::fields`) and its coloring.
    pub color_by: String,
    pub coloring: Coloring,
    pub width: u32,
    pub height: u32,
    /// Quit after this many frames (smoke tests); run until closed when `None`.
    pub frames: Option<u64>,
    pub validation: bool,
}

/// Orbit state around a target: azimuth around `up`, elevation towards it (radians).
struct Orbit {
    target: Vec3,
    distance: f32,
    azimuth: f32,
    elevation: f32,
    up: Up,
    home: Camera,
}

impl Orbit {
    fn from_camera(c: &Camera, up: Up) -> Self {
        let d = c.eye - c.target;
        let (azimuth, elevation) = orbit_angles(up, d);
        Self {
            target: c.target,
            distance: d.length().max(1e-6),
            azimuth,
            elevation,
            up,
            home: *c,
        }
    }

    /// The camera at the current angles: the up axis points up, except while looking straight
    /// along it (a home pose at ±90°, before any vertical drag), which keeps the home up vector.
    fn camera(&self) -> Camera {
        let dir = orbit_direction(self.up, self.azimuth, self.elevation);
        let along_axis = (self.elevation.abs() - std::f32::consts::FRAC_PI_2).abs() < 1e-4;
        Camera {
            eye: self.target + dir * self.distance,
            target: self.target,
            up: if along_axis {
                self.home.up
            } else {
                self.up.vector()
            },
            ..self.home
        }
    }

    fn pan(&mut self, delta: Vec2, height: f32) {
        let c = self.camera();
        let forward = (c.target - c.eye).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(c.up).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let scale = 2.0 * self.distance * (c.fov_y * 0.5).tan() / height.max(1.0);
        self.target += (-right * delta.x + up * delta.y) * scale;
    }
}

struct Gpu {
    renderer: Renderer,
    swapchain: Swapchain,
    window: Arc<Window>,
}

struct Viewer {
    opts: ViewerOptions,
    cloud: Cloud,
    ctx: Option<Arc<Context>>,
    scene: Option<(crate::methods::GpuScene, SceneInfo)>,
    gpu: Option<Gpu>,
    orbit: Orbit,
    method: usize,
    use_color: bool,
    drag: Option<(MouseButton, Vec2)>,
    cursor: Vec2,
    frames: u64,
    start: std::time::Instant,
    error: Option<anyhow::Error>,
}

/// Opens the viewer window on `cloud` and runs until it is closed.
pub fn run(cloud: Cloud, opts: ViewerOptions) -> Result<()> {
    let event_loop =
        EventLoop::new().context("cannot open a window system connection (is DISPLAY set?)")?;
    let method = METHODS
        .iter()
        .position(|m| m.name == opts.method.method.name)
        .unwrap_or(0);
    let mut viewer = Viewer {
        orbit: Orbit::from_camera(&opts.camera, opts.up),
        opts,
        cloud,
        ctx: None,
        scene: None,
        gpu: None,
        method,
        use_color: true,
        drag: None,
        cursor: Vec2::ZERO,
        frames: 0,
        start: std::time::Instant::now(),
        error: None,
    };
    event_loop.run_app(&mut viewer)?;
    if let Some(ctx) = &viewer.ctx {
        if ctx.validation && ctx.validation_errors() > 0 {
            anyhow::bail!("{} validation errors", ctx.validation_errors());
        }
    }
    viewer.error.map_or(Ok(()), Err)
}

impl Viewer {
    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let attrs = Window::default_attributes()
            .with_title(self.opts.title.clone())
            .with_inner_size(PhysicalSize::new(self.opts.width, self.opts.height));
        let window = Arc::new(event_loop.create_window(attrs)?);
        if self.ctx.is_none() {
            let display = event_loop.display_handle()?.as_raw();
            let exts = ash_window::enumerate_required_extensions(display)?
                .iter()
                // SAFETY: ash-window returns pointers to static extension-name strings.
                .map(|&p| unsafe { std::ffi::CStr::from_ptr(p) })
                .collect();
            let ctx = Arc::new(Context::new(&ContextOptions {
                validation: self.opts.validation,
                surface_extensions: exts,
            })?);
            self.scene = Some(upload_colored(&ctx, &self.cloud, self.opts.coloring)?);
            self.ctx = Some(ctx);
        }
        let ctx = self.ctx.clone().context("context")?;
        let size = window.inner_size();
        let swapchain = Swapchain::new(&ctx, &window, size.width.max(1), size.height.max(1))?;
        let renderer = self.build_renderer(&ctx, &swapchain)?;
        self.gpu = Some(Gpu {
            renderer,
            swapchain,
            window,
        });
        Ok(())
    }

    fn config(&self) -> MethodConfig {
        let m = &METHODS[self.method];
        if m.name == self.opts.method.method.name {
            self.opts.method.clone()
        } else {
            MethodConfig {
                method: m,
                params: Default::default(),
            }
        }
    }

    fn build_renderer(&self, ctx: &Arc<Context>, swapchain: &Swapchain) -> Result<Renderer> {
        let (scene, info) = self.scene.as_ref().context("scene not uploaded")?;
        let desc = ImageDesc {
            format: swapchain.format,
            width: swapchain.extent.width,
            height: swapchain.extent.height,
            mip_levels: 1,
            usage: ash::vk::ImageUsageFlags::TRANSFER_DST,
        };
        Renderer::new(
            ctx,
            scene,
            *info,
            &self.config(),
            swapchain.extent.width,
            swapchain.extent.height,
            Extras {
                readback: false,
                present: Some(desc),
                ..Extras::default()
            },
        )
    }

    fn rebuild(&mut self) -> Result<()> {
        let ctx = self.ctx.clone().context("context")?;
        if let Some(gpu) = self.gpu.as_mut() {
            let size = gpu.window.inner_size();
            if size.width == 0 || size.height == 0 {
                return Ok(());
            }
            gpu.swapchain.recreate(size.width, size.height)?;
        }
        if let Some(gpu) = self.gpu.take() {
            let renderer = self.build_renderer(&ctx, &gpu.swapchain)?;
            self.gpu = Some(Gpu { renderer, ..gpu });
        }
        Ok(())
    }

    fn switch_method(&mut self, step: isize) -> Result<()> {
        let has_faces = self
            .scene
            .as_ref()
            .is_some_and(|(s, _)| s.indices.is_some());
        let caps = self.ctx.as_ref().map(|c| c.caps.clone());
        for _ in 0..METHODS.len() {
            self.method = (self.method as isize + step).rem_euclid(METHODS.len() as isize) as usize;
            let m = &METHODS[self.method];
            let supported = caps.as_ref().is_none_or(|c| m.unsupported(c).is_none());
            if supported && (!m.needs_faces || has_faces) {
                break;
            }
        }
        self.rebuild()
    }

    /// Colors by the next field of `color::fields`: swaps the uploaded scalar stream (an event,
    /// not per frame) and rebuilds the renderer on the new segment table.
    fn cycle_color(&mut self) -> Result<()> {
        let fields = color::fields(&self.cloud);
        let name = color::next_field(&fields, &self.opts.color_by)
            .context("no field to color by")?
            .to_owned();
        let coloring =
            color::select(&self.cloud, &name, self.orbit.up).map_err(anyhow::Error::msg)?;
        let ctx = self.ctx.clone().context("context")?;
        if let Some((scene, info)) = self.scene.as_mut() {
            let chunk = crate::streams::UploadOptions::default().chunk_bytes;
            scene
                .streams
                .select_scalar(&ctx, &self.cloud, coloring.scalar, chunk)?;
            info.coloring = coloring;
        }
        println!("color by {name}");
        self.opts.color_by = name;
        self.rebuild()
    }

    fn frame(&mut self) -> Result<()> {
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        let size = gpu.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        if (size.width, size.height) != (gpu.swapchain.extent.width, gpu.swapchain.extent.height) {
            return self.rebuild();
        }
        // Waits only for the frame that used this slot last; the frame submitted just before
        // keeps running while this one is recorded.
        let available = gpu.renderer.begin_frame()?;
        let Some(index) = gpu.swapchain.acquire(available)? else {
            return self.rebuild();
        };
        let image = gpu.swapchain.images[index as usize];
        gpu.renderer
            .bind_present_image(image, ash::vk::ImageView::null());
        gpu.renderer.update(&View {
            camera: self.orbit.camera(),
            lights: self.opts.lights.clone(),
            use_color: self.use_color,
            time: self.start.elapsed().as_secs_f32(),
        })?;
        gpu.renderer.record(false)?;
        gpu.renderer.submit(
            Some(available),
            Some(gpu.swapchain.rendered[index as usize]),
        )?;
        let presented = gpu.swapchain.present(index)?;
        self.frames += 1;
        // The newest completed frame's timings (collected by `begin_frame`).
        let passes: Vec<String> = gpu
            .renderer
            .last_timings()
            .iter()
            .filter(|(n, _)| !n.starts_with("present"))
            .map(|(n, ms)| format!("{n} {ms:.2}"))
            .collect();
        gpu.window.set_title(&format!(
            "{} - {} - color: {} - {} ms{}",
            self.opts.title,
            gpu.renderer.config.label(),
            self.opts.color_by,
            passes.join(" | "),
            if self.use_color { "" } else { " (no color)" }
        ));
        if !presented {
            self.rebuild()?;
        }
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error = Some(e);
        self.gpu = None;
        event_loop.exit();
    }
}

impl ApplicationHandler for Viewer {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gpu.is_none() {
            if let Err(e) = self.init(event_loop) {
                self.fail(event_loop, e);
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                self.gpu = None;
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(_) => Ok(()),
            WindowEvent::RedrawRequested => self.frame(),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match event.logical_key.as_ref() {
                    Key::Named(NamedKey::Escape) => {
                        self.gpu = None;
                        event_loop.exit();
                        Ok(())
                    }
                    Key::Character("m") | Key::Named(NamedKey::Tab) => self.switch_method(1),
                    Key::Character("n") => self.switch_method(-1),
                    Key::Character("c") => {
                        self.use_color = !self.use_color;
                        Ok(())
                    }
                    Key::Character("v") => self.cycle_color(),
                    Key::Character("r") => {
                        self.orbit = Orbit::from_camera(&self.orbit.home, self.orbit.up);
                        Ok(())
                    }
                    _ => Ok(()),
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                self.drag = (state == ElementState::Pressed).then_some((button, self.cursor));
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                let p = Vec2::new(position.x as f32, position.y as f32);
                if let Some((button, last)) = self.drag {
                    let d = p - last;
                    match button {
                        MouseButton::Left => {
                            self.orbit.azimuth -= d.x * 0.01;
                            self.orbit.elevation =
                                (self.orbit.elevation + d.y * 0.01).clamp(-1.55, 1.55);
                        }
                        _ => {
                            let h = self
                                .gpu
                                .as_ref()
                                .map_or(1.0, |g| g.swapchain.extent.height as f32);
                            self.orbit.pan(d, h);
                        }
                    }
                    self.drag = Some((button, p));
                }
                self.cursor = p;
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.orbit.distance *= 0.9f32.powf(lines);
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.opts.frames.is_some_and(|n| self.frames >= n) {
            self.gpu = None;
            event_loop.exit();
            return;
        }
        if let Some(gpu) = &self.gpu {
            gpu.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drag_orbit_turns_about_the_up_axis_and_resets_home() {
        for up in [Up::Y, Up::Z] {
            let home = Camera::orbit_about(up, Vec3::ONE, 2.0, 30.0, 35.0, 1.0);
            let mut orbit = Orbit::from_camera(&home, up);
            let start = orbit.camera();
            assert!((start.eye - home.eye).length() < 1e-4, "{up}");
            assert_eq!(start.up, home.up);
            orbit.azimuth += 1.0;
            let turned = orbit.camera();
            let axis = up.vector();
            let expected =
                Vec3::ONE + glam::Quat::from_axis_angle(axis, 1.0) * (home.eye - Vec3::ONE);
            assert!(
                (turned.eye - expected).length() < 1e-4,
                "{up}: {}",
                turned.eye
            );
            assert_eq!(turned.up, axis);
            assert_eq!(Orbit::from_camera(&orbit.home, up).camera().eye, start.eye);
        }
        // Down from straight above a z-up scene, then to the horizon: +z stays up in the image.
        let top = Camera::orbit_about(Up::Z, Vec3::ZERO, 1.0, 0.0, 90.0, 1.0);
        let mut orbit = Orbit::from_camera(&top, Up::Z);
        assert_eq!(orbit.camera().up, top.up);
        orbit.azimuth = 1.5;
        orbit.elevation = 0.0;
        assert_eq!(orbit.camera().up, Vec3::Z);
    }
}

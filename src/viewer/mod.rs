//! The interactive viewer: a winit window, an ash swapchain, an orbit/pan/zoom camera, a HUD
//! drawn by the text overlay (method, per-pass GPU time, points, GPU memory, frame rate, key
//! help), screenshots, camera files and scripted tours. This module is the event loop and the
//! glue: the window, the renderer, keys, frames and scripts; `Viewer` holds the parts kept in
//! the other modules (the scene and its loading, the orbit, the drawing settings, the HUD, the
//! tools, the mouse).
//!
//! Keys are listed in `hud::KEYS` (the help panel shows them); real key events and script
//! `key` steps go through the same handler, `Viewer::press`.

mod camera_file;
mod drawing;
pub mod estimate;
pub mod hud;
mod hud_state;
mod input;
mod interact;
mod loading;
mod orbit;
mod playback;
pub mod script;
mod tool_state;
pub mod tools;
mod tour;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::raw_window_handle::HasDisplayHandle;
use winit::window::{Fullscreen, Window, WindowId};

use crate::color::Coloring;
use crate::frame::{write_png, Channels, Frame};
use crate::gpu::swapchain::Swapchain;
use crate::gpu::{Context, ContextOptions, ImageDesc};
use crate::gpu_scene::streamed::StreamOptions;
use crate::methods::{MethodConfig, METHODS};
use crate::post::PostOptions;
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::clip::Filter;
use crate::scene::scene_file::Bookmark;
use crate::scene::{Camera, Cloud, Light, Up};
pub use camera_file::{load_camera, save_camera, Saved};
use drawing::Drawing;
use estimate::EstimateOptions;
use hud_state::{legend_for, HudState};
use input::Pointer;
use loading::SceneState;
pub use loading::{run_loading, Early};
use orbit::Orbit;
pub use playback::PathPlay;
use playback::Playback;
use script::{Runner, Script, ViewerKey};
use tool_state::ToolState;

/// What the viewer shows.
pub struct ViewerOptions {
    pub title: String,
    /// The input's name, shown in the HUD.
    pub file: String,
    pub method: MethodConfig,
    pub camera: Camera,
    /// The axis the drag orbit turns about.
    pub up: Up,
    pub lights: Vec<Light>,
    /// Initial window size; `None`: 80 % of the monitor (1280x720 when it is unknown).
    pub size: Option<(u32, u32)>,
    /// Eye-dome lighting (at start; `E` toggles it) and background.
    pub post: PostOptions,
    /// The field colored by at start (`V` cycles `color::fields`) and its coloring.
    pub color_by: String,
    pub coloring: Coloring,
    /// Quit after this many frames (smoke tests); run until closed when `None`.
    pub frames: Option<u64>,
    pub validation: bool,
    /// A tour to run instead of waiting for input; the viewer quits at its end.
    pub script: Option<Script>,
    /// Where `K` saves and `L` loads the camera (a scene file).
    pub camera_file: PathBuf,
    /// Where `P` writes `surfel-<n>.png` (the current directory when `None`).
    pub screenshot_dir: Option<PathBuf>,
    /// Estimate the normals and radii the cloud lacks in the background, drawing the raw
    /// points meanwhile (a method that reads them waits for them).
    pub estimate: Option<EstimateOptions>,
    /// Stream this COPC file or URL by view (the viewer's cloud is then its root node).
    pub stream: Option<(String, StreamOptions)>,
    /// The clipping box and hidden classes at start (the scene file's).
    pub filter: Filter,
    /// Camera bookmarks at start (the scene file's).
    pub bookmarks: Vec<Bookmark>,
    /// A camera path to play and time at start (`A` plays it again).
    pub path: Option<PathPlay>,
}

/// The window, its swapchain and the renderer drawing into it.
struct Gpu {
    renderer: Renderer,
    swapchain: Swapchain,
    window: Arc<Window>,
}

/// The window, the renderer and what the viewer shows.
struct Viewer {
    /// The options given at start, with the method's parameters, colour field and lights as
    /// the keys changed them.
    opts: ViewerOptions,
    ctx: Option<Arc<Context>>,
    /// The window, its swapchain and the renderer (none before the window opens).
    gpu: Option<Gpu>,
    scene: SceneState,
    orbit: Orbit,
    drawing: Drawing,
    hud: HudState,
    tools: ToolState,
    pointer: Pointer,
    /// The scripted tour being run.
    script: Option<Runner>,
    /// The camera path being played (or played last).
    playback: Option<Playback>,
    /// A script's `size` step: the size asked for and the frames rendered since.
    resizing: Option<(PhysicalSize<u32>, u32)>,
    /// Write the next frame to these PNGs, in the order asked (`P`, a script's `screenshot`).
    screenshots: Vec<PathBuf>,
    quit: bool,
    /// Frames presented.
    frames: u64,
    start: Instant,
    /// The error that ended the event loop.
    error: Option<anyhow::Error>,
}

/// Opens the viewer window on `cloud` and runs until it is closed (or its script ends).
pub fn run(cloud: Cloud, opts: ViewerOptions) -> Result<()> {
    let event_loop =
        EventLoop::new().context("cannot open a window system connection (is DISPLAY set?)")?;
    let mut viewer = Viewer::new(cloud, opts);
    event_loop.run_app(&mut viewer)?;
    viewer.finish()
}

/// 80 % of the current (else the primary, else any) monitor; 1280x720 when none is known.
fn default_window_size(event_loop: &ActiveEventLoop) -> PhysicalSize<u32> {
    event_loop
        .primary_monitor()
        .or_else(|| event_loop.available_monitors().next())
        .map(|m| m.size())
        .filter(|s| s.width > 0 && s.height > 0)
        .map_or(PhysicalSize::new(1280, 720), |s| {
            PhysicalSize::new((s.width * 4 / 5).max(1), (s.height * 4 / 5).max(1))
        })
}

/// GPU memory in use and reserved by the context's allocator (every buffer and image).
fn gpu_memory(ctx: &Context) -> Option<(u64, u64)> {
    let guard = ctx.allocator.lock().ok()?;
    let report = guard.as_ref()?.generate_report();
    Some((report.total_allocated_bytes, report.total_capacity_bytes))
}

/// The first `surfel-<n>.png` (n = 1, 2, ...) that does not exist in `dir` (or the current
/// directory) and is not `pending`.
fn next_screenshot_path(dir: Option<&Path>, pending: &[PathBuf]) -> PathBuf {
    let mut n = 1u64;
    loop {
        let name = format!("surfel-{n}.png");
        let path = dir.map_or_else(|| PathBuf::from(&name), |d| d.join(&name));
        if !path.exists() && !pending.contains(&path) {
            return path;
        }
        n += 1;
    }
}

impl Viewer {
    fn new(cloud: Cloud, mut opts: ViewerOptions) -> Self {
        let method = METHODS
            .iter()
            .position(|m| m.name == opts.method.method.name)
            .unwrap_or(0);
        let script = opts.script.take().map(Runner::new);
        let playback = opts.path.take().map(Playback::new);
        let bookmarks = std::mem::take(&mut opts.bookmarks);
        Viewer {
            orbit: Orbit::from_camera(&opts.camera, opts.up),
            drawing: Drawing {
                method,
                use_color: true,
                post: opts.post,
            },
            hud: HudState::new(legend_for(&cloud, &opts.coloring)),
            tools: ToolState::new(opts.filter, bookmarks),
            scene: SceneState::new(cloud, opts.estimate.as_ref()),
            opts,
            ctx: None,
            gpu: None,
            pointer: Pointer::default(),
            script,
            playback,
            resizing: None,
            screenshots: Vec::new(),
            quit: false,
            frames: 0,
            start: Instant::now(),
            error: None,
        }
    }

    /// The viewer's outcome once its event loop ended: its error, else any validation error.
    fn finish(self) -> Result<()> {
        if let Some(ctx) = &self.ctx {
            if ctx.validation && ctx.validation_errors() > 0 {
                bail!(
                    "{} validation errors: {:#?}",
                    ctx.validation_errors(),
                    ctx.first_validation_errors()
                );
            }
        }
        self.error.map_or(Ok(()), Err)
    }

    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let size = self.opts.size.map_or_else(
            || default_window_size(event_loop),
            |(w, h)| PhysicalSize::new(w, h),
        );
        let attrs = Window::default_attributes()
            .with_title(self.opts.title.clone())
            .with_inner_size(size)
            .with_resizable(true);
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
            self.scene
                .open(&ctx, &self.opts, &METHODS[self.drawing.method])?;
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
        if self.tools.filter.is_active() {
            self.filter_changed()?;
        }
        Ok(())
    }

    fn build_renderer(&self, ctx: &Arc<Context>, swapchain: &Swapchain) -> Result<Renderer> {
        let (scene, info) = self.scene.drawn().context("scene not uploaded")?;
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
            RendererOptions {
                // Screenshots read the color target back (after the overlay drew on it).
                readback: true,
                present: Some(desc),
                overlay: true,
                post: self.drawing.post.for_display(),
                ..RendererOptions::default()
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
        if let Some(playback) = self.playback.as_mut() {
            playback.restart_if_timing();
        }
        self.push_filter();
        self.hud.dirty = true;
        Ok(())
    }

    /// The window's size in pixels (the swapchain's).
    fn size(&self) -> (u32, u32) {
        self.gpu.as_ref().map_or((1, 1), |g| {
            (g.swapchain.extent.width, g.swapchain.extent.height)
        })
    }

    /// Handles a key, from the window or from the script.
    fn press(&mut self, key: ViewerKey) -> Result<()> {
        self.hud.dirty = true;
        match key {
            ViewerKey::Escape => self.quit = true,
            ViewerKey::Tab => self.hud.visible = !self.hud.visible,
            ViewerKey::F11 => {
                if let Some(gpu) = &self.gpu {
                    let full = gpu.window.fullscreen().is_some();
                    gpu.window
                        .set_fullscreen((!full).then_some(Fullscreen::Borderless(None)));
                }
            }
            ViewerKey::Char('m') => self.switch_method(1)?,
            ViewerKey::Char('+' | '=') => self.scale_points(1.25)?,
            ViewerKey::Char('-') => self.scale_points(0.8)?,
            ViewerKey::Char('t') => {
                self.tools.next_tool();
                self.outcome(Ok(format!("tool: {}", self.tools.tool.name())))?;
            }
            ViewerKey::Char('x') => self.tools.clear(),
            ViewerKey::Char('b') => self.cycle_clip()?,
            ViewerKey::Char('f') => {
                self.tools.filter.hidden = Default::default();
                self.filter_changed()?;
            }
            ViewerKey::Char('u') => self.hud.expanded = !self.hud.expanded,
            ViewerKey::Ctrl(digit) => self.bookmark(digit as u8 - b'0', true)?,
            ViewerKey::Char('[') => self.step_level(-1)?,
            ViewerKey::Char(']') => self.step_level(1)?,
            ViewerKey::Char('n') => self.switch_method(-1)?,
            ViewerKey::Char('c') => self.drawing.use_color = !self.drawing.use_color,
            ViewerKey::Char('e') => self.toggle_edl()?,
            ViewerKey::Char('v') => self.cycle_color()?,
            ViewerKey::Char(',') => self.scale_any_budget(0.5)?,
            ViewerKey::Char('.') => self.scale_any_budget(2.0)?,
            ViewerKey::Char(digit @ '1'..='9') => self.bookmark(digit as u8 - b'0', false)?,
            ViewerKey::Char('g') => self.cycle_lights()?,
            ViewerKey::Char('r') => self.orbit.reset(),
            ViewerKey::Char('h') => self.hud.help = !self.hud.help,
            ViewerKey::Char('p') => {
                let path =
                    next_screenshot_path(self.opts.screenshot_dir.as_deref(), &self.screenshots);
                self.screenshots.push(path);
            }
            ViewerKey::Char('a') => {
                if let Some(playback) = self.playback.as_mut() {
                    playback.restart();
                }
            }
            ViewerKey::Char('k') => self.save_camera_file()?,
            ViewerKey::Char('l') => {
                let loaded = self.load_camera_file();
                self.outcome(loaded)?;
            }
            ViewerKey::Char(_) => {}
        }
        Ok(())
    }

    /// Reports an action's outcome in the HUD and on stdout. A failure stops a script (its
    /// error is the viewer's); interactively it is only reported.
    fn outcome(&mut self, result: Result<String>) -> Result<()> {
        match result {
            Ok(message) => {
                println!("{message}");
                self.hud.status = message;
                Ok(())
            }
            Err(e) if self.script.is_none() => {
                eprintln!("error: {e:#}");
                self.hud.status = format!("error: {e:#}");
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    fn frame(&mut self) -> Result<()> {
        if self.quit || self.gpu.is_none() {
            return Ok(());
        }
        let loading = self.poll_loading()?;
        if loading {
            let width = self.size().0;
            if let Some(loading) = &self.scene.loading {
                (self.hud.panels, self.hud.marks) = loading.screen(width);
            }
            self.hud.dirty = false;
        } else {
            // A scripted tour or a timed path waits for the estimate before its first step: its
            // screenshots and times do not depend on how fast the worker is.
            self.poll_estimation(self.script.is_some() || self.playback.is_some())?;
            if !self.run_script()? {
                self.quit = true;
                return Ok(());
            }
        }
        let Some(gpu) = self.gpu.as_ref() else {
            return Ok(());
        };
        let size = gpu.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        if (size.width, size.height) != (gpu.swapchain.extent.width, gpu.swapchain.extent.height) {
            self.rebuild()?;
        }
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        // Waits only for the frame that used this slot last; the frame submitted just before
        // keeps running while this one is recorded.
        let available = gpu.renderer.begin_frame()?;
        self.stream_nodes()?;
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        let Some(index) = gpu.swapchain.acquire(available)? else {
            return self.rebuild();
        };
        let shots = std::mem::take(&mut self.screenshots);
        let readback = !shots.is_empty() || !self.tools.requests.is_empty();
        let camera = if loading {
            self.orbit.camera()
        } else {
            self.next_camera()?
        };
        // After `begin_frame`, which collects the timings of the frame that used this slot:
        // while the renderer has none yet, every frame looks for them.
        if !loading && (self.hud.dirty || self.hud.measuring) {
            self.refresh_hud();
        }
        self.fill_marks(&camera);
        let Some(gpu) = self.gpu.as_mut() else {
            return Ok(());
        };
        let image = gpu.swapchain.images[index as usize];
        gpu.renderer
            .bind_present_image(image, ash::vk::ImageView::null());
        gpu.renderer.update(&View {
            camera,
            lights: self.opts.lights.clone(),
            use_color: self.drawing.use_color,
            time: self.start.elapsed().as_secs_f32(),
        })?;
        let (panels, marks) = self.hud.shown();
        gpu.renderer.set_overlay(panels, marks)?;
        gpu.renderer.record(readback)?;
        gpu.renderer.submit(
            Some(available),
            Some(gpu.swapchain.rendered[index as usize]),
        )?;
        let presented = gpu.swapchain.present(index)?;
        self.frames += 1;
        if readback {
            gpu.renderer.finish()?;
            let frame = gpu.renderer.read_frame()?;
            self.read_back(&frame, &camera, shots)?;
        }
        if !loading {
            self.path_frame_done()?;
        }
        if self.hud.rate.tick(Instant::now()) {
            self.hud.memory = self.ctx.as_deref().and_then(gpu_memory);
            self.hud.dirty = true;
        }
        if !presented {
            self.rebuild()?;
        }
        Ok(())
    }

    /// Writes the frame read back (rendered with `camera`) to the screenshots `shots` asked
    /// for, and runs the tool commands waiting for it.
    fn read_back(&mut self, frame: &Frame, camera: &Camera, shots: Vec<PathBuf>) -> Result<()> {
        for path in shots {
            let written = write_png(&path, frame, Channels::Rgb)
                .with_context(|| format!("{}: cannot write PNG", path.display()))
                .map(|()| format!("screenshot {}", path.display()));
            self.outcome(written)?;
            self.hud.dirty = true;
        }
        self.resolve_requests(frame, camera)
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
                self.quit = true;
                Ok(())
            }
            WindowEvent::Resized(_) => {
                self.hud.dirty = true;
                Ok(())
            }
            WindowEvent::RedrawRequested => self.frame(),
            WindowEvent::ModifiersChanged(m) => {
                self.pointer.ctrl = m.state().control_key();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match ViewerKey::from_winit(&event.logical_key, self.pointer.ctrl) {
                    Some(key) => self.press(key),
                    None => Ok(()),
                }
            }
            WindowEvent::MouseInput { state, button, .. } => self.mouse_input(button, state),
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor_moved(position);
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                self.mouse_wheel(delta);
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.quit || self.opts.frames.is_some_and(|n| self.frames >= n) {
            self.gpu = None;
            event_loop.exit();
            return;
        }
        if let Some(gpu) = &self.gpu {
            gpu.window.request_redraw();
        }
    }
}

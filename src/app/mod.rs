//! The interactive viewer: a winit window, an ash swapchain, an orbit/pan/zoom camera, a HUD
//! drawn by the text overlay (method, per-pass GPU time, points, GPU memory, frame rate, key
//! help), screenshots, camera files and scripted tours.
//!
//! Keys are listed in `hud::KEYS` (the help panel shows them); real key events and script
//! `key` steps go through the same handler, `Viewer::press`.

pub mod estimate;
pub mod hud;
mod interact;
pub mod script;
pub mod tools;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use glam::{DVec3, Vec2, Vec3};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::raw_window_handle::HasDisplayHandle;
use winit::window::{Fullscreen, Window, WindowId};

use crate::color::{self, Coloring, LegendEntry};
use crate::frame::Frame;
use crate::gpu::layout::COLOR_CLASSIFICATION;
use crate::gpu::swapchain::Swapchain;
use crate::gpu::{Context, ContextOptions, ImageDesc};
use crate::methods::{MethodConfig, METHODS};
use crate::overlay::{Mark, Panel};
use crate::post::PostOptions;
use crate::render::{Extras, Renderer, View, DEFAULT_FRAMES_IN_FLIGHT};
use crate::scene::camera::{orbit_angles, orbit_direction, Pose};
use crate::scene::clip::{ClipBox, Filter};
use crate::scene::scene_file::{Bookmark, SceneFile};
use crate::scene::{Camera, Cloud, Light, Up};
use crate::streams::upload::DEFAULT_CHUNK_BYTES;
use crate::upload::streamed::{StreamOptions, StreamedScene};
use crate::upload::{upload, GpuScene, SceneInfo, UploadOptions};
use estimate::{EstimateOptions, Estimation};
use hud::{FrameRate, Hud, Stats};
use interact::ClickTool;
use script::{Next, Runner, Script, Tool, ViewerKey};

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
    scene: Option<(GpuScene, SceneInfo)>,
    /// A streamed file's scene (instead of `scene`).
    streamed: Option<StreamedScene>,
    gpu: Option<Gpu>,
    orbit: Orbit,
    method: usize,
    use_color: bool,
    /// The HUD is drawn (`Tab`).
    hud_visible: bool,
    /// The key help is shown (`H`).
    help: bool,
    /// The HUD's panels, rebuilt when `hud_dirty` (state changes, and twice a second).
    panels: Vec<Panel>,
    hud_dirty: bool,
    /// The last action's outcome, shown in the HUD.
    status: String,
    rate: FrameRate,
    /// GPU allocator bytes (allocated, reserved), sampled with the frame rate.
    memory: Option<(u64, u64)>,
    script: Option<Runner>,
    /// A script's `size` step: the size asked for and the frames rendered since.
    resizing: Option<(PhysicalSize<u32>, u32)>,
    /// Write the next frame to these PNGs, in the order asked (`P`, a script's `screenshot`).
    screenshots: Vec<PathBuf>,
    quit: bool,
    /// The post-processing shown now (`E` switches EDL on and off).
    post: PostOptions,
    /// The classification legend while coloring by classification (shown in the HUD).
    legend: Vec<LegendEntry>,
    drag: Option<(MouseButton, Vec2)>,
    cursor: Vec2,
    frames: u64,
    start: Instant,
    error: Option<anyhow::Error>,
    /// Normals and radii being estimated in the background.
    estimation: Option<Estimation>,
    /// What a left click does (`T`).
    tool: ClickTool,
    /// The current tool's picked points (file coordinates) and what they measure.
    picks: Vec<DVec3>,
    measured: Vec<(&'static str, f64)>,
    /// The clipping box and hidden classes the projection passes apply.
    filter: Filter,
    /// The last clipping box set (kept, not drawn, while clipping is off: `B` turns it back on).
    clip_box: Option<ClipBox>,
    /// `hpr::spacing` of the cloud for picking (computed on the first pick).
    spacing: Option<f64>,
    /// Tool commands waiting for the next frame's depth.
    requests: Vec<Tool>,
    bookmarks: Vec<Bookmark>,
    /// The renderer has finished no timed frame yet (after a start, a method, parameter or
    /// size change): the HUD says it is measuring and is rebuilt every frame until it has.
    measuring: bool,
    /// The HUD lists every pass (`U`) instead of per-family totals.
    expanded: bool,
    /// Ctrl is held.
    ctrl: bool,
    /// The file being loaded (the window shows its progress; the viewer starts when it is done).
    loading: Option<Loading>,
    /// Where the left button went down (a release within a few pixels is a click).
    press: Option<Vec2>,
    /// The HUD's solid quads (the colour ramp's scale bar), rebuilt with the panels.
    hud_marks: Vec<Mark>,
    /// This frame's marks (`fill_marks`), kept for the next frame's.
    frame_marks: Vec<Mark>,
    /// The stats panel's legend lines: the index of the first and the classes.
    legend_rows: (usize, Vec<u32>),
}

/// The HUD's classification legend: the classes present while coloring by classification.
fn legend_for(cloud: &Cloud, coloring: &Coloring) -> Vec<LegendEntry> {
    if coloring.mode == COLOR_CLASSIFICATION {
        color::legend(cloud)
    } else {
        Vec::new()
    }
}

/// Opens the viewer window on `cloud` and runs until it is closed (or its script ends).
pub fn run(cloud: Cloud, opts: ViewerOptions) -> Result<()> {
    let event_loop =
        EventLoop::new().context("cannot open a window system connection (is DISPLAY set?)")?;
    let mut viewer = Viewer::new(cloud, opts);
    event_loop.run_app(&mut viewer)?;
    viewer.finish()
}

/// What the window needs before the file is loaded.
pub struct Early {
    pub title: String,
    /// The input's name, shown while it loads.
    pub file: String,
    pub size: Option<(u32, u32)>,
    pub validation: bool,
}

/// A load running on a worker thread while the window shows its progress.
struct Loading {
    handle: std::thread::JoinHandle<Result<(Cloud, ViewerOptions)>>,
    file: String,
    started: Instant,
}

/// Opens the window at once and shows the progress of `load` (run on a worker thread: the
/// stage and percentage of the newest progress bar, `scene::progress::current`) until it
/// returns the cloud and the viewer's options; then views them. A failed load is the viewer's
/// error.
pub fn run_loading(
    early: Early,
    load: impl FnOnce() -> Result<(Cloud, ViewerOptions)> + Send + 'static,
) -> Result<()> {
    let event_loop =
        EventLoop::new().context("cannot open a window system connection (is DISPLAY set?)")?;
    // One point behind the camera: a blank frame under the progress overlay.
    let placeholder = Cloud {
        positions: vec![Vec3::ZERO],
        ..Cloud::default()
    };
    let opts = ViewerOptions {
        title: early.title,
        file: early.file.clone(),
        method: MethodConfig::parse("points")?,
        camera: Camera::look_at_up(Up::Y, Vec3::Z, Vec3::Z * 2.0, 1.0),
        up: Up::Y,
        lights: vec![Light::headlight()],
        size: early.size,
        post: PostOptions::NONE,
        color_by: "none".into(),
        coloring: color::Coloring::default_for(false),
        frames: None,
        validation: early.validation,
        script: None,
        camera_file: PathBuf::from("surfel-camera.toml"),
        screenshot_dir: None,
        estimate: None,
        stream: None,
        filter: Filter::default(),
        bookmarks: Vec::new(),
    };
    let mut viewer = Viewer::new(placeholder, opts);
    viewer.loading = Some(Loading {
        handle: std::thread::spawn(load),
        file: early.file,
        started: Instant::now(),
    });
    event_loop.run_app(&mut viewer)?;
    viewer.finish()
}

/// Pixels the cursor may move between press and release of a click.
const CLICK_SLOP: f32 = 3.0;

/// Rounds of 100 ms a scripted frame waits for a streamed view's nodes.
const STREAM_WAIT_ROUNDS: u32 = 600;

/// Frames a script's `size` step waits for the window to take its size.
const RESIZE_FRAMES: u32 = 500;

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

/// Writes the frame's color as an opaque RGB PNG (what the window shows).
pub fn write_png(path: &Path, frame: &Frame) -> Result<()> {
    let rgb: Vec<u8> = frame
        .color
        .iter()
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    image::save_buffer(
        path,
        &rgb,
        frame.width,
        frame.height,
        image::ExtendedColorType::Rgb8,
    )
    .with_context(|| format!("{}: cannot write PNG", path.display()))
}

/// What the viewer saves in its camera file besides the camera.
pub struct Saved<'a> {
    pub up: Up,
    pub lights: &'a [Light],
    pub filter: &'a Filter,
    pub bookmarks: &'a [Bookmark],
    /// The local frame's origin in file coordinates (`Cloud::origin`).
    pub origin: DVec3,
}

/// Saves `camera` (in the file's coordinates), the up axis, lights, clipping box, hidden
/// classes and bookmarks as a scene file `--scene` reads back; the post-processing and
/// coloring settings are not part of a camera and stay unset.
pub fn save_camera(path: &Path, camera: &Camera, saved: &Saved<'_>) -> Result<()> {
    let file = |p: Vec3| (saved.origin + p.as_dvec3()).to_array();
    SceneFile {
        up: Some(saved.up),
        camera: Some(Pose::LookAt {
            eye: file(camera.eye),
            target: file(camera.target),
        }),
        lights: saved.lights.to_vec(),
        edl: None,
        background: None,
        color_by: None,
        inputs: Vec::new(),
        hidden_classes: saved.filter.hidden.list(),
        clip: saved.filter.clip,
        bookmarks: saved.bookmarks.to_vec(),
    }
    .save(path)
}

/// The camera of the scene file at `path` for a scene with this bounding sphere and local
/// origin, orbiting about `up` unless the file names its own up axis; and the file.
pub fn load_camera(
    path: &Path,
    (centre, radius): (Vec3, f32),
    up: Up,
    origin: DVec3,
) -> Result<(Camera, SceneFile)> {
    let file = SceneFile::load(path)?;
    let pose = file
        .camera
        .with_context(|| format!("{}: the scene file has no camera", path.display()))?;
    Ok((
        pose.camera(centre, radius, file.up.unwrap_or(up), origin),
        file,
    ))
}

impl Viewer {
    fn new(cloud: Cloud, mut opts: ViewerOptions) -> Self {
        let method = METHODS
            .iter()
            .position(|m| m.name == opts.method.method.name)
            .unwrap_or(0);
        let script = opts.script.take().map(Runner::new);
        let estimation = opts.estimate.as_ref().map(|o| Estimation::start(&cloud, o));
        let bookmarks = std::mem::take(&mut opts.bookmarks);
        Viewer {
            orbit: Orbit::from_camera(&opts.camera, opts.up),
            post: opts.post,
            legend: legend_for(&cloud, &opts.coloring),
            filter: opts.filter,
            clip_box: opts.filter.clip,
            bookmarks,
            opts,
            cloud,
            ctx: None,
            scene: None,
            streamed: None,
            gpu: None,
            method,
            use_color: true,
            hud_visible: true,
            help: false,
            panels: Vec::new(),
            hud_dirty: true,
            status: String::new(),
            rate: FrameRate::new(Instant::now()),
            memory: None,
            script,
            resizing: None,
            screenshots: Vec::new(),
            quit: false,
            drag: None,
            cursor: Vec2::ZERO,
            frames: 0,
            start: Instant::now(),
            error: None,
            estimation,
            tool: ClickTool::Pick,
            picks: Vec::new(),
            measured: Vec::new(),
            spacing: None,
            requests: Vec::new(),
            measuring: true,
            expanded: false,
            ctrl: false,
            press: None,
            hud_marks: Vec::new(),
            frame_marks: Vec::new(),
            legend_rows: (0, Vec::new()),
            loading: None,
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

    /// Takes the loaded cloud and options when the load is done (its error is the viewer's);
    /// true while it still runs.
    fn poll_loading(&mut self) -> Result<bool> {
        let Some(loading) = &self.loading else {
            return Ok(false);
        };
        if !loading.handle.is_finished() {
            return Ok(true);
        }
        let Some(loading) = self.loading.take() else {
            return Ok(false);
        };
        let (cloud, opts) = loading.handle.join().map_err(|_| {
            anyhow::anyhow!("loading {} failed: the loader panicked", loading.file)
        })??;
        let ctx = self.ctx.take();
        let gpu = self.gpu.take();
        *self = Viewer::new(cloud, opts);
        self.ctx = ctx;
        self.gpu = gpu;
        let ctx = self.ctx.clone().context("context")?;
        let options =
            METHODS[self.method].upload_options(UploadOptions::colored(self.opts.coloring));
        self.scene = Some(upload(&ctx, &self.cloud, &options)?);
        if let Some(gpu) = &self.gpu {
            gpu.window.set_title(&self.opts.title);
        }
        self.rebuild()?;
        if self.filter.is_active() {
            self.filter_changed()?;
        }
        Ok(false)
    }

    /// The load screen: what loads, the stage and its percentage, and a bar (`hud_marks`).
    fn loading_panels(&mut self, width: u32) {
        let Some(loading) = &self.loading else {
            return;
        };
        let (stage, percent) = crate::scene::progress::current().unwrap_or(("reading", 0));
        let mut panel = Panel::new(crate::overlay::Corner::TopLeft);
        panel.line(
            format!("loading {}", loading.file),
            crate::overlay::HudLine::HEADING,
        );
        panel.line(
            format!(
                "{stage} {percent} %   {:.1} s",
                loading.started.elapsed().as_secs_f64()
            ),
            crate::overlay::HudLine::TEXT,
        );
        self.panels = vec![panel];
        let line = crate::overlay::atlas().map_or(18.0, |a| a.line_height);
        let margin = crate::overlay::MARGIN;
        let top = margin + 2.0 * line + 2.0 * crate::overlay::PADDING + 6.0;
        let w = (width as f32 - 2.0 * margin).clamp(1.0, 400.0);
        let filled = w * percent.min(100) as f32 / 100.0;
        self.hud_marks = vec![
            Mark {
                rect: glam::Vec4::new(margin, top, margin + w, top + 10.0),
                color: crate::overlay::PANEL_COLOR,
            },
            Mark {
                rect: glam::Vec4::new(margin, top, margin + filled, top + 10.0),
                color: crate::overlay::HudLine::HEADING,
            },
        ];
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
            // The object texture and the normal fields only when the viewer starts on a method
            // reading them.
            let method = &METHODS[self.method];
            if let Some((location, options)) = &self.opts.stream {
                let coloring = self.opts.coloring;
                self.streamed = Some(StreamedScene::open(
                    &ctx,
                    location,
                    options,
                    |_| Ok(coloring),
                    DEFAULT_FRAMES_IN_FLIGHT,
                )?);
            } else {
                let options = method.upload_options(UploadOptions::colored(self.opts.coloring));
                self.scene = Some(upload(&ctx, &self.cloud, &options)?);
            }
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
        if self.filter.is_active() {
            self.filter_changed()?;
        }
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
        let (scene, info) = match &self.streamed {
            Some(s) => (&s.scene, &s.info),
            None => {
                let (scene, info) = self.scene.as_ref().context("scene not uploaded")?;
                (scene, info)
            }
        };
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
                // Screenshots read the color target back (after the overlay drew on it).
                readback: true,
                present: Some(desc),
                overlay: true,
                post: self.post.for_display(),
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
        self.push_filter();
        self.hud_dirty = true;
        Ok(())
    }

    fn switch_method(&mut self, step: isize) -> Result<()> {
        let has_faces = self
            .scene
            .as_ref()
            .is_some_and(|(s, _)| s.indices.is_some());
        let caps = self.ctx.as_ref().map(|c| c.caps.clone());
        // Normals and radii the cloud has or will have (none with `--k 0`).
        let surfels = (self.cloud.normals.is_some() && self.cloud.radii.is_some())
            || self.estimation.is_some();
        for _ in 0..METHODS.len() {
            self.method = (self.method as isize + step).rem_euclid(METHODS.len() as isize) as usize;
            let m = &METHODS[self.method];
            let supported = caps.as_ref().is_none_or(|c| m.unsupported(c).is_none());
            // A streamed file has only the nodes in view, and the normal fields when asked.
            let streamable = self.streamed.as_ref().is_none_or(|s| {
                !(m.needs_lod || m.needs_hpr || m.needs_faces)
                    && (!m.needs_normal_field || s.scene.streams.normal_field)
                    && (!m.needs_surfels || s.info.has_normals)
            });
            let surfels = surfels || self.streamed.is_some();
            if supported
                && streamable
                && (!m.needs_faces || has_faces)
                && (!m.needs_surfels || surfels)
            {
                break;
            }
        }
        self.upload_what_the_method_reads()?;
        println!("method {}", METHODS[self.method].name);
        self.rebuild()
    }

    /// Adds to the uploaded scene what the method reads and the scene was uploaded without
    /// (`GpuScene::complete`): an event, not per frame.
    fn upload_what_the_method_reads(&mut self) -> Result<()> {
        let method = &METHODS[self.method];
        if method.needs_surfels {
            self.poll_estimation(true)?;
        }
        let (Some(ctx), Some((scene, _))) = (self.ctx.clone(), self.scene.as_mut()) else {
            return Ok(());
        };
        scene.complete(
            &ctx,
            &self.cloud,
            &method.upload_options(Default::default()),
        )?;
        Ok(())
    }

    /// Takes the background estimate when it is done (waiting for it when `wait`): the cloud
    /// gets its normals and radii and is uploaded again, lit from then on.
    fn poll_estimation(&mut self, wait: bool) -> Result<()> {
        let Some(done) = self
            .estimation
            .as_ref()
            .map(|e| e.poll(wait))
            .transpose()?
            .flatten()
        else {
            return Ok(());
        };
        self.estimation = None;
        self.cloud.normals = Some(done.normals);
        self.cloud.radii = Some(done.radii);
        if let (Some(ctx), Some((_, info))) = (self.ctx.clone(), self.scene.as_ref()) {
            let coloring = info.coloring;
            let options = METHODS[self.method].upload_options(UploadOptions::colored(coloring));
            self.scene = Some(upload(&ctx, &self.cloud, &options)?);
            self.rebuild()?;
        }
        if let Some(e) = done.cache_error {
            self.outcome(Err(anyhow::anyhow!(e)))?;
        }
        self.outcome(Ok(format!(
            "normals and radii ready after {:.2} s: lit shading",
            done.seconds
        )))
    }

    /// For a method with a `show` parameter (the pyramid's), shows the next coarser (`step` 1)
    /// or finer level: -1 is the reconstruction, 0 the raw projection, N level N of the analysis.
    fn step_level(&mut self, step: i32) -> Result<()> {
        let mut config = self.config();
        let Some(spec) = config.method.params.iter().find(|p| p.name == "show") else {
            return self.outcome(Ok(format!("{} shows no levels", config.method.name)));
        };
        let level = (config.get("show") + step as f32).clamp(spec.min, spec.max);
        config.params.insert("show".into(), level);
        self.opts.method = config;
        self.rebuild()?;
        let what = match level as i32 {
            -1 => "the reconstruction".to_string(),
            0 => "level 0 as projected".to_string(),
            l => format!("level {l} of the analysis"),
        };
        self.outcome(Ok(format!("showing {what}")))
    }

    /// Colors by the next field of `color::fields`: swaps the uploaded scalar stream (an event,
    /// not per frame) and rebuilds the renderer on the new segment table.
    fn cycle_color(&mut self) -> Result<()> {
        if self.streamed.is_some() {
            // Reported, not failed: a scripted tour goes on.
            let e = "V is off for a streamed file: its colour field is chosen when it opens \
                     (--color-by)";
            println!("{}", serde_json::json!({ "error": e }));
            return self.outcome(Ok(e.into()));
        }
        let fields = color::fields(&self.cloud);
        let name = color::next_field(&fields, &self.opts.color_by)
            .context("no field to color by")?
            .to_owned();
        let coloring =
            color::select(&self.cloud, &name, self.orbit.up).map_err(anyhow::Error::msg)?;
        let ctx = self.ctx.clone().context("context")?;
        if let Some((scene, info)) = self.scene.as_mut() {
            scene
                .streams
                .select_scalar(&ctx, &self.cloud, coloring.scalar, DEFAULT_CHUNK_BYTES)?;
            info.coloring = coloring;
        }
        self.legend = legend_for(&self.cloud, &coloring);
        println!("color by {name}");
        self.opts.color_by = name;
        self.rebuild()
    }

    /// Scales a streamed file's point budget by `factor` (at least one node's worth).
    fn scale_budget(&mut self, factor: f64) -> Result<()> {
        let streamed = self
            .streamed
            .as_mut()
            .context("the point budget is for streamed files (--stream)")?;
        let budget = ((streamed.point_budget() as f64 * factor) as u64).max(10_000);
        streamed.set_point_budget(budget);
        println!("point budget {budget}");
        self.hud_dirty = true;
        Ok(())
    }

    /// Switches eye-dome lighting off, or on with the parameters given at start (else the
    /// defaults), and rebuilds the graph.
    fn toggle_edl(&mut self) -> Result<()> {
        self.post.edl = match self.post.edl {
            Some(_) => None,
            None => Some(self.opts.post.edl.unwrap_or_default()),
        };
        self.rebuild()
    }

    /// Handles a key, from the window or from the script.
    fn press(&mut self, key: ViewerKey) -> Result<()> {
        self.hud_dirty = true;
        match key {
            ViewerKey::Escape => self.quit = true,
            ViewerKey::Tab => self.hud_visible = !self.hud_visible,
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
                let at = ClickTool::ALL
                    .iter()
                    .position(|t| *t == self.tool)
                    .unwrap_or(0);
                self.tool = ClickTool::ALL[(at + 1) % ClickTool::ALL.len()];
                self.picks.clear();
                self.measured.clear();
                self.outcome(Ok(format!("tool: {}", self.tool.name())))?;
            }
            ViewerKey::Char('x') => {
                self.picks.clear();
                self.measured.clear();
            }
            ViewerKey::Char('b') => self.cycle_clip()?,
            ViewerKey::Char('f') => {
                self.filter.hidden = Default::default();
                self.filter_changed()?;
            }
            ViewerKey::Char('u') => self.expanded = !self.expanded,
            ViewerKey::Ctrl(digit) => self.bookmark(digit as u8 - b'0', true)?,
            ViewerKey::Char('[') => self.step_level(-1)?,
            ViewerKey::Char(']') => self.step_level(1)?,
            ViewerKey::Char('n') => self.switch_method(-1)?,
            ViewerKey::Char('c') => self.use_color = !self.use_color,
            ViewerKey::Char('e') => self.toggle_edl()?,
            ViewerKey::Char('v') => self.cycle_color()?,
            ViewerKey::Char(',') => self.scale_any_budget(0.5)?,
            ViewerKey::Char('.') => self.scale_any_budget(2.0)?,
            ViewerKey::Char(digit @ '1'..='9') => self.bookmark(digit as u8 - b'0', false)?,
            ViewerKey::Char('g') => {
                let count = (self.opts.lights.len() as u32 + 1) % 10;
                let radius = self.scene.as_ref().map_or(1.0, |(_, info)| info.radius);
                self.opts.lights = crate::scene::lights::sweep(count, radius);
                self.outcome(Ok(format!("lights: {count}")))?;
            }
            ViewerKey::Char('r') => {
                self.orbit = Orbit::from_camera(&self.orbit.home, self.orbit.up)
            }
            ViewerKey::Char('h') => self.help = !self.help,
            ViewerKey::Char('p') => {
                let path =
                    next_screenshot_path(self.opts.screenshot_dir.as_deref(), &self.screenshots);
                self.screenshots.push(path);
            }
            ViewerKey::Char('k') => {
                let path = self.opts.camera_file.clone();
                let saved = save_camera(
                    &path,
                    &self.orbit.camera(),
                    &Saved {
                        up: self.orbit.up,
                        lights: &self.opts.lights,
                        filter: &self.filter,
                        bookmarks: &self.bookmarks,
                        origin: self.cloud.origin,
                    },
                );
                self.outcome(saved.map(|()| format!("camera saved to {}", path.display())))?;
            }
            ViewerKey::Char('l') => {
                let loaded = self.load_camera();
                self.outcome(loaded)?;
            }
            ViewerKey::Char(_) => {}
        }
        Ok(())
    }

    fn load_camera(&mut self) -> Result<String> {
        let info = match (&self.scene, &self.streamed) {
            (Some((_, info)), _) => info,
            (None, Some(s)) => &s.info,
            _ => bail!("scene not uploaded"),
        };
        let path = self.opts.camera_file.clone();
        let (camera, file) = load_camera(
            &path,
            (info.centre, info.radius),
            self.orbit.up,
            self.cloud.origin,
        )?;
        let home = self.orbit.home;
        self.orbit = Orbit::from_camera(&camera, self.orbit.up);
        self.orbit.home = home;
        self.filter = file.filter();
        if file.clip.is_some() {
            self.clip_box = file.clip;
        }
        self.bookmarks = file.bookmarks;
        self.filter_changed()?;
        Ok(format!("camera loaded from {}", path.display()))
    }

    /// Reports an action's outcome in the HUD and on stdout. A failure stops a script (its
    /// error is the viewer's); interactively it is only reported.
    fn outcome(&mut self, result: Result<String>) -> Result<()> {
        match result {
            Ok(message) => {
                println!("{message}");
                self.status = message;
                Ok(())
            }
            Err(e) if self.script.is_none() => {
                eprintln!("error: {e:#}");
                self.status = format!("error: {e:#}");
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    /// Rebuilds the HUD's panels and the window title from the newest figures.
    fn refresh_hud(&mut self) {
        if let Some(e) = &self.estimation {
            self.status = format!(
                "estimating normals and radii (k = {}): {} %",
                e.k,
                e.percent()
            );
        }
        let tool_lines = self.tool_lines();
        if let Some(s) = &self.streamed {
            // A streamed file's classes are those of the nodes loaded so far.
            if s.info.coloring.mode == COLOR_CLASSIFICATION {
                self.legend = s.legend();
            }
        }
        let Some(gpu) = self.gpu.as_mut() else {
            return;
        };
        let passes: Vec<(String, f64)> = gpu
            .renderer
            .last_timings()
            .into_iter()
            .filter(|(n, _)| !n.starts_with("present"))
            .collect();
        let label = gpu.renderer.config.label();
        // A rebuilt renderer has no timings until its first frame's timestamps are collected
        // (when its slot comes round again, after the frames in flight): until then the HUD
        // says it is measuring, never showing another renderer's passes.
        self.measuring = passes.is_empty();
        let projected = match &self.scene {
            _ if gpu.renderer.config.method.needs_lod => {
                hud::Projected::LevelOfDetail(gpu.renderer.samples_per_level().map(<[u64]>::to_vec))
            }
            Some((scene, _)) if gpu.renderer.config.method.culls_batches => {
                let camera = self.orbit.camera();
                let aspect = gpu.renderer.width as f32 / gpu.renderer.height.max(1) as f32;
                let view_proj = camera.projection(aspect) * camera.view();
                hud::Projected::InView(crate::streams::projected_points(
                    view_proj,
                    &scene.streams.host_batches,
                ))
            }
            _ => hud::Projected::All,
        };
        let stream = self.streamed.as_ref().map(|s| {
            let t = s.stats();
            format!(
                "streamed {} of {} points, budget {} (, .)\n{}nodes {}, loading {}, read {:.1} MB, pool {} of {}{}",
                hud::thousands(t.drawn_points),
                hud::thousands(t.selected_points),
                hud::thousands(s.point_budget()),
                if t.tiles > 1 {
                    format!("tiles open {} of {}, ", t.tiles_open, t.tiles)
                } else {
                    String::new()
                },
                t.selected_nodes,
                t.loading,
                t.bytes_read as f64 / 1e6,
                t.used_slots,
                t.slots,
                if t.failed > 0 { format!(", {} skipped", t.failed) } else { String::new() }
            )
        });
        let points = match &self.streamed {
            Some(s) => s.stats().drawn_points,
            None => u64::from(gpu.renderer.info.points),
        };
        let hud = Hud::new(
            &Stats {
                method: &label,
                file: &self.opts.file,
                passes: &passes,
                points,
                stream: stream.as_deref(),
                projected,
                width: gpu.renderer.width,
                height: gpu.renderer.height,
                fps: self.rate.fps,
                memory: self.memory,
                use_color: self.use_color,
                edl: self.post.edl,
                color_by: &self.opts.color_by,
                legend: &self.legend,
                status: &self.status,
                expanded: self.expanded,
                measuring: self.measuring,
                hidden: &self.filter.hidden,
                tools: &tool_lines,
            },
            self.help,
        );
        self.legend_rows = (hud.legend_at, self.legend.iter().map(|e| e.class).collect());
        self.panels = hud.panels();
        let (width, height) = (gpu.renderer.width, gpu.renderer.height);
        let coloring = gpu.renderer.info.coloring;
        let ms: Vec<String> = passes
            .iter()
            .map(|(n, ms)| format!("{n} {ms:.2}"))
            .collect();
        gpu.window.set_title(&format!(
            "{} - {} - color: {} - {} ms{}{}",
            self.opts.title,
            label,
            self.opts.color_by,
            ms.join(" | "),
            if self.use_color { "" } else { " (no color)" },
            if self.measuring { " (measuring)" } else { "" }
        ));
        self.hud_marks.clear();
        if let Some(panel) = self.scale_bar(coloring, width, height) {
            self.panels.push(panel);
        }
        self.hud_dirty = false;
    }

    /// The colour ramp's scale bar (bottom left) while coloring by a ramp: a panel naming the
    /// field and its range, and the ramp's steps as marks above it (`hud_marks`); while coloring
    /// by return number, the palette's key.
    fn scale_bar(&mut self, coloring: Coloring, width: u32, height: u32) -> Option<Panel> {
        if coloring.mode == crate::gpu::layout::COLOR_RETURN {
            // The return palette's key.
            let mut panel = Panel::new(crate::overlay::Corner::BottomLeft);
            for number in 1..=5 {
                let [r, g, b] = color::return_color(number);
                let what = if number == 5 {
                    "return 5 and later".to_string()
                } else {
                    format!("return {number}")
                };
                panel.line(what, [r, g, b, 255]);
            }
            return Some(panel);
        }
        color::ramp_color(coloring.mode, 0.0)?;
        // Elevations are local: the scale names the file's.
        let shift = if coloring.mode == crate::gpu::layout::COLOR_ELEVATION {
            self.cloud.origin.dot(coloring.axis.as_dvec3())
        } else {
            0.0
        };
        let [lo, hi] = coloring.range.map(|v| f64::from(v) + shift);
        let mut panel = Panel::new(crate::overlay::Corner::BottomLeft);
        panel.line(
            format!("{}  {lo:.4} to {hi:.4}", self.opts.color_by),
            crate::overlay::HudLine::TEXT,
        );
        let line = crate::overlay::atlas().map_or(18.0, |a| a.line_height);
        let margin = crate::overlay::MARGIN;
        let panel_h = line + 2.0 * crate::overlay::PADDING;
        let (bar_w, bar_h) = (256.0f32.min(width as f32 - 2.0 * margin), 12.0);
        let bottom = height as f32 - margin - panel_h - 4.0;
        let steps = 64;
        for k in 0..steps {
            let t = (k as f32 + 0.5) / steps as f32;
            let [r, g, b] = color::ramp_color(coloring.mode, t)?;
            let x0 = margin + bar_w * k as f32 / steps as f32;
            self.hud_marks.push(Mark {
                rect: glam::Vec4::new(x0, bottom - bar_h, x0 + bar_w / steps as f32 + 0.5, bottom),
                color: [r, g, b, 255],
            });
        }
        Some(panel)
    }

    /// Runs script steps up to the next frame; returns false when the script is over.
    fn run_script(&mut self) -> Result<bool> {
        if let (Some((size, waited)), Some(gpu)) = (self.resizing.as_mut(), self.gpu.as_ref()) {
            let now = gpu.window.inner_size();
            if now != *size {
                // The window system resizes asynchronously: keep rendering meanwhile.
                *waited += 1;
                if *waited > RESIZE_FRAMES {
                    bail!(
                        "the window did not resize to {}x{} within {RESIZE_FRAMES} frames (it is {}x{})",
                        size.width,
                        size.height,
                        now.width,
                        now.height
                    );
                }
                return Ok(true);
            }
            self.resizing = None;
        }
        while let Some(runner) = self.script.as_mut() {
            match runner.step() {
                Next::Key(k) => self.press(k)?,
                Next::Orbit(az, el) => {
                    self.orbit.azimuth = az.to_radians();
                    self.orbit.elevation = el.to_radians().clamp(-1.55, 1.55);
                }
                Next::Size(w, h) => {
                    let size = PhysicalSize::new(w, h);
                    if let Some(gpu) = &self.gpu {
                        // `None`: the size is applied later, reported by a `Resized` event.
                        let _ = gpu.window.request_inner_size(size);
                    }
                    self.resizing = Some((size, 0));
                    return self.run_script();
                }
                Next::Frame(shot) => {
                    self.screenshots.extend(shot);
                    return Ok(true);
                }
                Next::Tool(Tool::Click(x, y)) => {
                    // A legend line toggles its class at once; a pick waits for a frame.
                    if self.click(x, y)? {
                        return Ok(true);
                    }
                }
                Next::Tool(tool) if tool.needs_frame() => {
                    // Runs on the next frame's depth.
                    self.requests.push(tool);
                    return Ok(true);
                }
                Next::Tool(tool) => self.tool_now(tool)?,
                Next::Quit => return Ok(false),
            }
            if self.quit {
                return Ok(false);
            }
        }
        Ok(true)
    }

    fn frame(&mut self) -> Result<()> {
        if self.quit || self.gpu.is_none() {
            return Ok(());
        }
        let loading = self.poll_loading()?;
        if loading {
            let width = self.size().0;
            self.loading_panels(width);
            self.hud_dirty = false;
        } else {
            // A scripted tour waits for the estimate before its first step: its screenshots do
            // not depend on how fast the worker is.
            self.poll_estimation(self.script.is_some())?;
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
        if let Some(streamed) = self.streamed.as_mut() {
            // Nodes arrive and leave between frames; never waits for the file or the network.
            streamed.update(
                &self.orbit.camera(),
                gpu.swapchain.extent.width,
                gpu.swapchain.extent.height,
            )?;
            // A scripted tour draws each frame of a view once its nodes are all resident, so
            // its screenshots do not depend on how fast the file is read.
            let camera = self.orbit.camera();
            let mut rounds = 0;
            while self.script.is_some() && !streamed.stable() && !streamed.waits_for_slots() {
                rounds += 1;
                if rounds > STREAM_WAIT_ROUNDS {
                    bail!(
                        "streaming made no progress for {} s",
                        STREAM_WAIT_ROUNDS / 10
                    );
                }
                streamed.wait(std::time::Duration::from_millis(100));
                streamed.refine(
                    &camera,
                    gpu.swapchain.extent.width,
                    gpu.swapchain.extent.height,
                )?;
            }
            gpu.renderer.set_batches(streamed.batches())?;
            let classes = streamed.info.coloring.mode == COLOR_CLASSIFICATION;
            if classes && streamed.legend_classes() != self.legend.len() {
                // A class arrived with a node: its legend line appears at once.
                self.hud_dirty = true;
            }
            for m in streamed.take_messages() {
                eprintln!("warning: {m}");
                self.status = m;
                self.hud_dirty = true;
            }
        }
        let Some(index) = gpu.swapchain.acquire(available)? else {
            return self.rebuild();
        };
        let shots = std::mem::take(&mut self.screenshots);
        let readback = !shots.is_empty() || !self.requests.is_empty();
        let camera = self.orbit.camera();
        // After `begin_frame`, which collects the timings of the frame that used this slot:
        // while the renderer has none yet, every frame looks for them.
        if !loading && (self.hud_dirty || self.measuring) {
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
            use_color: self.use_color,
            time: self.start.elapsed().as_secs_f32(),
        })?;
        let (panels, marks): (&[Panel], &[Mark]) = if self.hud_visible {
            (&self.panels, &self.frame_marks)
        } else {
            (&[], &[])
        };
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
            for path in shots {
                let written =
                    write_png(&path, &frame).map(|()| format!("screenshot {}", path.display()));
                self.outcome(written)?;
                self.hud_dirty = true;
            }
            self.resolve_requests(&frame, &camera)?;
        }
        if self.rate.tick(Instant::now()) {
            self.memory = self.ctx.as_deref().and_then(gpu_memory);
            self.hud_dirty = true;
        }
        if !presented {
            self.rebuild()?;
        }
        Ok(())
    }

    /// A left click at a window pixel: on a legend line of the HUD as it stands it toggles the
    /// class, elsewhere the current tool picks there on the next frame's depth (then it returns
    /// true).
    fn click(&mut self, x: i32, y: i32) -> Result<bool> {
        if self.hud_dirty {
            self.refresh_hud();
        }
        if let Some(class) = self.legend_class_at(x as f32, y as f32) {
            match u8::try_from(class) {
                Ok(c) => self.toggle_class(c)?,
                Err(_) => {
                    self.outcome(Ok("values that are not classes cannot be hidden".into()))?
                }
            }
            return Ok(false);
        }
        self.requests.push(Tool::Click(x, y));
        Ok(true)
    }

    /// The legend class whose HUD line is at window pixel (x, y), if any.
    fn legend_class_at(&self, x: f32, y: f32) -> Option<u32> {
        let panel = self.panels.first().filter(|_| self.hud_visible)?;
        let atlas = crate::overlay::atlas().ok()?;
        let row = crate::overlay::line_at(atlas, panel, (x, y))?;
        let (first, classes) = &self.legend_rows;
        row.checked_sub(*first)
            .and_then(|k| classes.get(k))
            .copied()
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
                self.hud_dirty = true;
                Ok(())
            }
            WindowEvent::RedrawRequested => self.frame(),
            WindowEvent::ModifiersChanged(m) => {
                self.ctrl = m.state().control_key();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match ViewerKey::from_winit(&event.logical_key, self.ctrl) {
                    Some(key) => self.press(key),
                    None => Ok(()),
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let pressed = state == ElementState::Pressed;
                self.drag = pressed.then_some((button, self.cursor));
                match (button, pressed, self.press) {
                    (MouseButton::Left, true, _) => {
                        self.press = Some(self.cursor);
                        Ok(())
                    }
                    (MouseButton::Left, false, Some(at)) => {
                        self.press = None;
                        // A release where the button went down is a click, not a drag.
                        if (self.cursor - at).length() <= CLICK_SLOP {
                            self.click(self.cursor.x as i32, self.cursor.y as i32)
                                .map(|_| ())
                        } else {
                            Ok(())
                        }
                    }
                    _ => Ok(()),
                }
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

    #[test]
    fn a_saved_camera_loads_back_unchanged() {
        let dir = std::env::temp_dir().join(format!("surfel-camera-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let (centre, radius) = (Vec3::new(1.0, -2.0, 0.5), 3.0);
        let camera = Camera::orbit_about(Up::Z, centre, radius, 33.3, 21.7, 1.1);
        // A UTM-sized local origin: the file holds the file's coordinates.
        let origin = DVec3::new(512_345.5, 4_123_456.25, 100.0);
        let filter = Filter {
            clip: Some(ClipBox::aligned(origin, origin + DVec3::ONE)),
            hidden: crate::scene::clip::Classes::from_list(&[2, 7]),
        };
        let bookmarks = [Bookmark {
            slot: 3,
            eye: [512_400.0, 4_123_400.0, 300.0],
            target: [512_345.0, 4_123_456.0, 100.0],
        }];
        let saved = Saved {
            up: Up::Z,
            lights: &[Light::headlight()],
            filter: &filter,
            bookmarks: &bookmarks,
            origin,
        };
        for name in ["cam.toml", "cam.json"] {
            let path = dir.join(name);
            save_camera(&path, &camera, &saved).expect("save");
            let file = SceneFile::load(&path).expect("parses");
            assert_eq!(file.up, Some(Up::Z));
            assert_eq!(file.lights, vec![Light::headlight()]);
            assert_eq!(
                file.camera,
                Some(Pose::LookAt {
                    eye: (origin + camera.eye.as_dvec3()).to_array(),
                    target: (origin + camera.target.as_dvec3()).to_array(),
                })
            );
            assert_eq!(file.filter(), filter);
            assert_eq!(file.bookmarks, bookmarks);
            // Loaded about another axis: the file's own up axis wins.
            let (loaded, _) = load_camera(&path, (centre, radius), Up::Y, origin).expect("load");
            assert!((loaded.eye - camera.eye).length() < 1e-5, "{loaded:?}");
            assert!((loaded.target - camera.target).length() < 1e-5);
            assert_eq!(loaded.up, camera.up);
        }
        let bad = dir.join("cam.txt");
        let e = save_camera(&bad, &camera, &saved).unwrap_err();
        assert!(format!("{e:#}").contains("cam.txt"), "{e:#}");
        let at = (centre, radius);
        let e = load_camera(&dir.join("missing.toml"), at, Up::Z, origin).unwrap_err();
        assert!(format!("{e:#}").contains("missing.toml"), "{e:#}");
        std::fs::write(dir.join("nocam.toml"), "up = \"z\"\n").expect("write");
        let e = load_camera(&dir.join("nocam.toml"), at, Up::Z, origin).unwrap_err();
        assert!(format!("{e:#}").contains("has no camera"), "{e:#}");
    }
}

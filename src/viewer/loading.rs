//! What the viewer draws and how it gets there: `SceneState` holds the cloud, its upload or a
//! streamed file's scene, and the work still bringing data in: a file loading on a worker
//! thread while the window shows its progress, and normals and radii estimated in the
//! background. A streamed file's nodes for the view are taken here every frame.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _, Result};
use glam::{Vec3, Vec4};
use winit::event_loop::EventLoop;

use super::estimate::{EstimateOptions, Estimation};
use super::{Viewer, ViewerOptions};
use crate::color::{self, Coloring};
use crate::gpu::Context;
use crate::gpu_scene::streamed::StreamedScene;
use crate::gpu_scene::{upload, GpuScene, SceneInfo, UploadOptions};
use crate::layout::COLOR_CLASSIFICATION;
use crate::methods::{MethodConfig, MethodInfo, METHODS};
use crate::overlay::{Corner, HudLine, Mark, Panel};
use crate::post::PostOptions;
use crate::render::DEFAULT_FRAMES_IN_FLIGHT;
use crate::scene::clip::Filter;
use crate::scene::{Camera, Cloud, Light, Up};

/// Rounds of 100 ms a scripted frame waits for a streamed view's nodes.
const STREAM_WAIT_ROUNDS: u32 = 600;

/// What the window needs before the file is loaded.
pub struct Early {
    pub title: String,
    /// The input's name, shown while it loads.
    pub file: String,
    pub size: Option<(u32, u32)>,
    pub validation: bool,
}

/// A load running on a worker thread while the window shows its progress.
pub(super) struct Loading {
    handle: std::thread::JoinHandle<Result<(Cloud, ViewerOptions)>>,
    file: String,
    started: Instant,
}

impl Loading {
    /// The cloud and options the load returned (its error, or a panic reported as one).
    fn join(self) -> Result<(Cloud, ViewerOptions)> {
        self.handle
            .join()
            .map_err(|_| anyhow::anyhow!("loading {} failed: the loader panicked", self.file))?
    }

    /// The load screen in a window `width` pixels wide: what loads, the stage and its
    /// percentage, and a bar (its marks).
    pub fn screen(&self, width: u32) -> (Vec<Panel>, Vec<Mark>) {
        let (stage, percent) = crate::scene::progress::current().unwrap_or(("reading", 0));
        let mut panel = Panel::new(Corner::TopLeft);
        panel.line(format!("loading {}", self.file), HudLine::HEADING);
        panel.line(
            format!(
                "{stage} {percent} %   {:.1} s",
                self.started.elapsed().as_secs_f64()
            ),
            HudLine::TEXT,
        );
        let line = crate::overlay::atlas().map_or(18.0, |a| a.line_height);
        let margin = crate::overlay::MARGIN;
        let top = margin + 2.0 * line + 2.0 * crate::overlay::PADDING + 6.0;
        let w = (width as f32 - 2.0 * margin).clamp(1.0, 400.0);
        let filled = w * percent.min(100) as f32 / 100.0;
        let marks = vec![
            Mark {
                rect: Vec4::new(margin, top, margin + w, top + 10.0),
                color: crate::overlay::PANEL_COLOR,
            },
            Mark {
                rect: Vec4::new(margin, top, margin + filled, top + 10.0),
                color: HudLine::HEADING,
            },
        ];
        (vec![panel], marks)
    }
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
        path: None,
    };
    let mut viewer = Viewer::new(placeholder, opts);
    viewer.scene.loading = Some(Loading {
        handle: std::thread::spawn(load),
        file: early.file,
        started: Instant::now(),
    });
    event_loop.run_app(&mut viewer)?;
    viewer.finish()
}

/// The viewed data: the cloud on the host, what of it reached the GPU (its upload, or a
/// streamed file's scene), and the work still bringing data in.
pub(super) struct SceneState {
    /// The cloud (a streamed file's root node).
    pub cloud: Cloud,
    /// The uploaded cloud and its figures (none for a streamed file).
    pub uploaded: Option<(GpuScene, SceneInfo)>,
    /// A streamed file's scene (instead of `uploaded`).
    pub streamed: Option<StreamedScene>,
    /// Normals and radii being estimated in the background.
    pub estimation: Option<Estimation>,
    /// The file being loaded (the window shows its progress; the viewer starts when it is done).
    pub loading: Option<Loading>,
}

impl SceneState {
    /// `cloud` with nothing on the GPU yet; its estimate starts when `estimate` asks for one.
    pub fn new(cloud: Cloud, estimate: Option<&EstimateOptions>) -> Self {
        let estimation = estimate.map(|o| Estimation::start(&cloud, o));
        Self {
            cloud,
            uploaded: None,
            streamed: None,
            estimation,
            loading: None,
        }
    }

    /// Opens the file `opts` streams, else uploads the cloud with what `method` reads (the
    /// object texture and the normal fields only when the viewer starts on a method reading
    /// them).
    pub fn open(
        &mut self,
        ctx: &Arc<Context>,
        opts: &ViewerOptions,
        method: &MethodInfo,
    ) -> Result<()> {
        if let Some((location, options)) = &opts.stream {
            let coloring = opts.coloring;
            self.streamed = Some(StreamedScene::open(
                ctx,
                location,
                options,
                |_| Ok(coloring),
                DEFAULT_FRAMES_IN_FLIGHT,
            )?);
            Ok(())
        } else {
            self.upload(ctx, method, opts.coloring)
        }
    }

    /// Uploads the cloud with what `method` reads, colored by `coloring`.
    pub fn upload(
        &mut self,
        ctx: &Arc<Context>,
        method: &MethodInfo,
        coloring: Coloring,
    ) -> Result<()> {
        let options = method.upload_options(UploadOptions::colored(coloring));
        self.uploaded = Some(upload(ctx, &self.cloud, &options)?);
        Ok(())
    }

    /// The scene drawn and its figures: a streamed file's, else the uploaded cloud's.
    pub fn drawn(&self) -> Option<(&GpuScene, &SceneInfo)> {
        match &self.streamed {
            Some(s) => Some((&s.scene, &s.info)),
            None => self.uploaded.as_ref().map(|(scene, info)| (scene, info)),
        }
    }
}

impl Viewer {
    /// Takes the loaded cloud and options when the load is done (its error is the viewer's);
    /// true while it still runs.
    pub(super) fn poll_loading(&mut self) -> Result<bool> {
        let Some(loading) = &self.scene.loading else {
            return Ok(false);
        };
        if !loading.handle.is_finished() {
            return Ok(true);
        }
        let Some(loading) = self.scene.loading.take() else {
            return Ok(false);
        };
        let (cloud, opts) = loading.join()?;
        let ctx = self.ctx.take();
        let gpu = self.gpu.take();
        *self = Viewer::new(cloud, opts);
        self.ctx = ctx;
        self.gpu = gpu;
        let ctx = self.ctx.clone().context("context")?;
        let coloring = self.opts.coloring;
        self.scene
            .upload(&ctx, &METHODS[self.drawing.method], coloring)?;
        if let Some(gpu) = &self.gpu {
            gpu.window.set_title(&self.opts.title);
        }
        self.rebuild()?;
        if self.tools.filter.is_active() {
            self.filter_changed()?;
        }
        Ok(false)
    }

    /// Takes the background estimate when it is done (waiting for it when `wait`): the cloud
    /// gets its normals and radii and is uploaded again, lit from then on.
    pub(super) fn poll_estimation(&mut self, wait: bool) -> Result<()> {
        let Some(done) = self
            .scene
            .estimation
            .as_ref()
            .map(|e| e.poll(wait))
            .transpose()?
            .flatten()
        else {
            return Ok(());
        };
        self.scene.estimation = None;
        self.scene.cloud.normals = Some(done.normals);
        self.scene.cloud.radii = Some(done.radii);
        if let (Some(ctx), Some((_, info))) = (self.ctx.clone(), self.scene.uploaded.as_ref()) {
            let coloring = info.coloring;
            self.scene
                .upload(&ctx, &METHODS[self.drawing.method], coloring)?;
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

    /// A streamed file's nodes for this frame's view, handed to the renderer; never waits for
    /// the file or the network, except in a scripted tour, which draws a view once its nodes
    /// are all resident (so its screenshots do not depend on how fast the file is read).
    pub(super) fn stream_nodes(&mut self) -> Result<()> {
        let (Some(streamed), Some(gpu)) = (self.scene.streamed.as_mut(), self.gpu.as_mut()) else {
            return Ok(());
        };
        let (width, height) = (gpu.swapchain.extent.width, gpu.swapchain.extent.height);
        // Nodes arrive and leave between frames.
        streamed.update(&self.orbit.camera(), width, height)?;
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
            streamed.wait(Duration::from_millis(100));
            streamed.refine(&camera, width, height)?;
        }
        gpu.renderer.set_batches(streamed.batches())?;
        let classes = streamed.info.coloring.mode == COLOR_CLASSIFICATION;
        if classes && streamed.legend_classes() != self.hud.legend.len() {
            // A class arrived with a node: its legend line appears at once.
            self.hud.dirty = true;
        }
        for m in streamed.take_messages() {
            eprintln!("warning: {m}");
            self.hud.status = m;
            self.hud.dirty = true;
        }
        Ok(())
    }
}

//! `surfel view`: the interactive viewer (or a scripted tour of it).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use glam::Vec3;

use super::render::{StreamArgs, TimingOutputArgs};
use super::{check_surfels, estimates, view_settings, CameraArgs, InputArgs};
use crate::color;
use crate::frame::Size;
use crate::gpu_scene::streamed::StreamOptions;
use crate::methods::MethodConfig;
use crate::render::settings::ViewSettings;
use crate::scene::path::CameraPath;
use crate::scene::{compose, Cloud};
use crate::viewer::estimate::EstimateOptions;
use crate::viewer::script::Script;
use crate::viewer::{PathPlay, ViewerOptions};

#[derive(Args, Debug)]
pub struct ViewArgs {
    pub file: PathBuf,
    #[arg(long, short, default_value = "points")]
    pub method: String,
    /// Initial window size WxH (default: 80 % of the monitor).
    #[arg(long)]
    pub size: Option<String>,
    /// Quit after N frames (smoke tests).
    #[arg(long)]
    pub frames: Option<u64>,
    #[arg(long)]
    pub validation: bool,
    /// Run a tour: one command per line (`key NAME`, `frames N`, `screenshot PATH`,
    /// `orbit AZ,EL`, `quit`), then quit.
    #[arg(long, conflicts_with = "path")]
    pub script: Option<PathBuf>,
    /// Play a camera path (TOML keyframes, `scene::path`) at start, timing every frame (`A`
    /// plays it again); with --timings, --timings-csv or --trace, write them and quit.
    #[arg(long, value_name = "TOML")]
    pub path: Option<PathBuf>,
    /// Frames rendered at the path's first pose before its frames are timed.
    #[arg(long, default_value_t = 3, requires = "path")]
    pub warmup: u32,
    #[command(flatten)]
    pub outputs: TimingOutputArgs,
    /// Scene file where `K` saves and `L` loads the camera (.toml or .json).
    #[arg(long, default_value = "surfel-camera.toml")]
    pub camera_file: PathBuf,
    /// Directory for `P` screenshots (surfel-<n>.png; default: the current directory), created
    /// when missing.
    #[arg(long)]
    pub screenshot_dir: Option<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub stream: StreamArgs,
}

pub(super) fn view(a: ViewArgs) -> Result<()> {
    let config = MethodConfig::parse(&a.method)?;
    let size = a
        .size
        .as_deref()
        .map(|s| Size::parse(s).map(Size::pair))
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let settings = view_settings(&a.camera)?;
    let script = a
        .script
        .as_deref()
        .map(crate::viewer::script::Script::load)
        .transpose()?;
    crate::viewer::script::check_camera_file(&a.camera_file)?;
    let path = a.path.as_deref().map(CameraPath::load).transpose()?;
    if path.is_none() && a.outputs.outputs().any() {
        bail!("--timings, --timings-csv and --trace time a camera path in the viewer: give --path");
    }
    if let Some(dir) = &a.screenshot_dir {
        std::fs::create_dir_all(dir).map_err(|e| {
            anyhow::anyhow!(
                "{}: cannot create the screenshot directory: {e}",
                dir.display()
            )
        })?;
    }
    let start = Start {
        a,
        config,
        size,
        settings,
        script,
        path,
    };
    if start.a.stream.streams(&start.a.file) {
        return view_streamed(start);
    }
    let title = format!("surfel - {}", start.a.file.display());
    let file = start.a.file.file_name().map_or_else(
        || start.a.file.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let early = crate::viewer::Early {
        title: title.clone(),
        file: file.clone(),
        size,
        validation: validation(&start.a),
    };
    // The window opens at once and shows the load's progress.
    crate::viewer::run_loading(early, move || load(start, (title, file)))
}

/// What `view` read from its command line, for the viewer's options.
struct Start {
    a: ViewArgs,
    config: MethodConfig,
    size: Option<(u32, u32)>,
    settings: ViewSettings,
    script: Option<Script>,
    path: Option<CameraPath>,
}

fn validation(a: &ViewArgs) -> bool {
    a.validation || crate::gpu::context::validation_requested()
}

/// The viewer's options for `cloud` (the loaded cloud, or a streamed file's root node) framed
/// by the bounding sphere `(centre, radius)`, titled `(title, file)`.
fn viewer_options(
    s: Start,
    cloud: &Cloud,
    (centre, radius): (Vec3, f32),
    (title, file): (String, String),
    estimate: Option<EstimateOptions>,
    stream: Option<(String, StreamOptions)>,
) -> Result<ViewerOptions> {
    let coloring = s.settings.coloring(&s.a.file, cloud)?;
    let color_by = s
        .settings
        .color_by
        .clone()
        .unwrap_or_else(|| color::default_field(cloud).to_owned());
    let up = s.settings.up(cloud.up);
    let camera = s.settings.camera(centre, radius, up, cloud.origin);
    let path = s.path.map(|path| PathPlay {
        cameras: path.cameras(&|pose| pose.camera(centre, radius, up, cloud.origin)),
        times: path.times(),
        warmup: s.a.warmup,
        outputs: s.a.outputs.outputs(),
    });
    Ok(ViewerOptions {
        title,
        file,
        method: s.config,
        camera,
        up,
        lights: s.settings.lights,
        size: s.size,
        filter: s.settings.filter,
        bookmarks: s.settings.bookmarks,
        post: s.settings.post,
        color_by,
        coloring,
        frames: s.a.frames,
        validation: validation(&s.a),
        script: s.script,
        camera_file: s.a.camera_file,
        screenshot_dir: s.a.screenshot_dir,
        estimate,
        stream,
        path,
    })
}

/// Loads the file for the viewer and makes its options (on the viewer's loading thread).
fn load(s: Start, shown: (String, String)) -> Result<(Cloud, ViewerOptions)> {
    let (cloud, _) = compose::load(
        &s.a.file,
        &s.settings.inputs,
        &s.a.input.options(estimates(s.config.method, &s.settings)),
        &crate::scene::input::estimate_on_cpu,
    )?;
    check_surfels(s.config.method, &cloud, &s.a.file)?;
    // What the first method does not read is estimated while the viewer shows the raw points.
    let lacking = cloud.normals.is_none() || cloud.radii.is_none();
    let estimate = (lacking && s.a.input.k > 0).then(|| EstimateOptions {
        k: s.a.input.k,
        cache: (s.a.input.cache && s.settings.inputs.is_empty()).then(|| s.a.file.clone()),
    });
    let sphere = cloud.bounding_sphere().unwrap_or((Vec3::ZERO, 1.0));
    let options = viewer_options(s, &cloud, sphere, shown, estimate, None)?;
    Ok((cloud, options))
}

/// The viewer on a streamed COPC file or virtual point cloud: its (central file's) root node
/// opens first (for the colour field and the camera), the viewer streams the rest by view.
fn view_streamed(s: Start) -> Result<()> {
    let location = s.a.file.to_string_lossy().into_owned();
    let k = if s.config.method.needs_surfels {
        s.a.input.k
    } else {
        0
    };
    let options = s.a.stream.options(k, s.config.method.needs_normal_field);
    let opened = crate::copc::loader::Loader::open(&location, options.loader.clone())?;
    let (lo, hi) = opened.loader.local_bounds();
    let root = opened.root;
    drop(opened.loader);
    let sphere = (
        (lo + hi) * 0.5,
        ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE),
    );
    let shown = (
        format!("surfel - {location} (streamed)"),
        location.rsplit('/').next().unwrap_or(&location).to_owned(),
    );
    let stream = Some((location.clone(), options));
    let options = viewer_options(s, &root, sphere, shown, None, stream)?;
    crate::viewer::run(root, options)
}

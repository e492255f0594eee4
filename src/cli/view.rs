//! `surfel view`: the interactive viewer (or a scripted tour of it).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::render::StreamArgs;
use super::{check_surfels, estimates, view_settings, CameraArgs, InputArgs};
use crate::color;
use crate::frame::Size;
use crate::methods::MethodConfig;
use crate::scene::compose;

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
    #[arg(long)]
    pub script: Option<PathBuf>,
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
        .map(crate::app::script::Script::load)
        .transpose()?;
    crate::app::script::check_camera_file(&a.camera_file)?;
    if let Some(dir) = &a.screenshot_dir {
        std::fs::create_dir_all(dir).map_err(|e| {
            anyhow::anyhow!(
                "{}: cannot create the screenshot directory: {e}",
                dir.display()
            )
        })?;
    }
    if a.stream.streams(&a.file) {
        return view_streamed(a, config, size, settings, script);
    }
    let file_name = a.file.file_name().map_or_else(
        || a.file.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let early = crate::app::Early {
        title: format!("surfel - {}", a.file.display()),
        file: file_name,
        size,
        validation: a.validation || crate::gpu::context::validation_requested(),
    };
    // The window opens at once and shows the load's progress.
    crate::app::run_loading(early, move || load(a, config, size, settings, script))
}

/// Loads the file for the viewer and makes its options (on the viewer's loading thread).
fn load(
    a: ViewArgs,
    config: MethodConfig,
    size: Option<(u32, u32)>,
    settings: crate::render::settings::ViewSettings,
    script: Option<crate::app::script::Script>,
) -> Result<(crate::scene::Cloud, crate::app::ViewerOptions)> {
    let (cloud, _) = compose::load(
        &a.file,
        &settings.inputs,
        &a.input.options(estimates(config.method, &settings)),
        &crate::scene::input::estimate_on_cpu,
    )?;
    check_surfels(config.method, &cloud, &a.file)?;
    // What the first method does not read is estimated while the viewer shows the raw points.
    let lacking = cloud.normals.is_none() || cloud.radii.is_none();
    let estimate = (lacking && a.input.k > 0).then(|| crate::app::estimate::EstimateOptions {
        k: a.input.k,
        cache: (a.input.cache && settings.inputs.is_empty()).then(|| a.file.clone()),
    });
    let coloring = settings.coloring(&a.file, &cloud)?;
    let color_by = settings
        .color_by
        .clone()
        .unwrap_or_else(|| color::default_field(&cloud).to_owned());
    let (centre, radius) = cloud.bounding_sphere().unwrap_or((glam::Vec3::ZERO, 1.0));
    let up = settings.up(cloud.up);
    let camera = settings.camera(centre, radius, up, cloud.origin);
    Ok((
        cloud,
        crate::app::ViewerOptions {
            title: format!("surfel - {}", a.file.display()),
            file: a.file.file_name().map_or_else(
                || a.file.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            ),
            method: config,
            camera,
            up,
            lights: settings.lights,
            size,
            filter: settings.filter,
            bookmarks: settings.bookmarks.clone(),
            post: settings.post,
            color_by,
            coloring,
            frames: a.frames,
            validation: a.validation || crate::gpu::context::validation_requested(),
            script,
            camera_file: a.camera_file,
            screenshot_dir: a.screenshot_dir,
            estimate,
            stream: None,
        },
    ))
}

/// The viewer on a streamed COPC file: its root node opens first (for the colour field and
/// the camera), the viewer streams the rest by view.
fn view_streamed(
    a: ViewArgs,
    config: MethodConfig,
    size: Option<(u32, u32)>,
    settings: crate::render::settings::ViewSettings,
    script: Option<crate::app::script::Script>,
) -> Result<()> {
    let location = a.file.to_string_lossy().into_owned();
    let k = if config.method.needs_surfels {
        a.input.k
    } else {
        0
    };
    let options = a.stream.options(k, config.method.needs_normal_field);
    let opened = crate::stream::loader::Loader::open(&location, options.loader.clone())?;
    let (lo, hi) = opened.loader.local_bounds();
    let root = opened.root;
    drop(opened.loader);
    let coloring = settings.coloring(&a.file, &root)?;
    let color_by = settings
        .color_by
        .clone()
        .unwrap_or_else(|| color::default_field(&root).to_owned());
    let up = settings.up(root.up);
    let (centre, radius) = (
        (lo + hi) * 0.5,
        ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE),
    );
    let camera = settings.camera(centre, radius, up, root.origin);
    crate::app::run(
        root,
        crate::app::ViewerOptions {
            title: format!("surfel - {location} (streamed)"),
            file: location.rsplit('/').next().unwrap_or(&location).to_owned(),
            method: config,
            camera,
            up,
            lights: settings.lights,
            size,
            filter: settings.filter,
            bookmarks: settings.bookmarks.clone(),
            post: settings.post,
            color_by,
            coloring,
            frames: a.frames,
            validation: a.validation || crate::gpu::context::validation_requested(),
            script,
            camera_file: a.camera_file,
            screenshot_dir: a.screenshot_dir,
            estimate: None,
            stream: Some((location, options)),
        },
    )
}

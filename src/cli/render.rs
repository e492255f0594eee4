//! `surfel render`: one method's frames of a file, headless, to a PNG and timings.

use std::path::PathBuf;

use anyhow::{bail, Context as _, Result};
use clap::Args;
use serde::Serialize;

use super::{check_surfels, context, estimates, view_settings, CameraArgs, InputArgs};
use crate::copc::loader::LoaderOptions;
use crate::eval::timing::{self, measure, FramePlan, RunMeta, Study};
use crate::frame::Size;
use crate::gpu_scene::streamed::{
    StreamOptions, StreamedScene, DEFAULT_ERROR_PX, DEFAULT_POINT_BUDGET,
};
use crate::gpu_scene::{upload, UploadOptions};
use crate::hpr::view::HprView;
use crate::knn_gpu::EstimateOn;
use crate::methods::hpr::visible::{visible_points, Algorithm, Request};
use crate::methods::{MethodConfig, METHODS};
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::compose;
use crate::scene::path::CameraPath;
use crate::scene::preprocess;
use crate::scene::{Cloud, Estimator};
use crate::source::{HttpOptions, DEFAULT_CONNECTIONS};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Model or point cloud (ply, obj, pcd, las, laz, copc.laz, e57, xyz).
    #[arg(required_unless_present = "list_methods")]
    pub file: Option<PathBuf>,
    /// Method, optionally with parameters: `points:size=3`.
    #[arg(long, short, default_value = "points")]
    pub method: String,
    /// Image size WxH.
    #[arg(long, default_value = "1024x1024")]
    pub size: String,
    /// Output PNG.
    #[arg(long, short, default_value = "surfel.png")]
    pub out: PathBuf,
    #[command(flatten)]
    pub outputs: TimingOutputArgs,
    /// Frames rendered before timing starts (pipelines, caches and thread pools settle).
    #[arg(long, default_value_t = 3)]
    pub warmup: u32,
    /// Timed frames (at least), 1 to 1024.
    #[arg(long, default_value_t = 20)]
    pub frames: u32,
    /// Time frames for at least this many seconds (past --frames, up to 1024 frames).
    #[arg(long, default_value_t = 0.0, value_name = "S")]
    pub min_time: f64,
    /// Render and time every frame along a camera path (TOML keyframes, `scene::path`); the
    /// PNG is its last frame.
    #[arg(long, value_name = "TOML")]
    pub path: Option<PathBuf>,
    /// Also count each pass's vertex, fragment and compute shader invocations (pipeline
    /// statistics queries around every pass, which may perturb the times beside them).
    #[arg(long)]
    pub pipeline_stats: bool,
    /// Print the render graph's schedule (passes, accesses, barriers).
    #[arg(long)]
    pub dump_graph: bool,
    /// Print the available methods, one per line, and exit.
    #[arg(long)]
    pub list_methods: bool,
    /// Render only the points visible from the camera (hidden point removal, 003).
    #[arg(long, value_enum)]
    pub visibility: Option<Visibility>,
    /// Enable the Vulkan validation layers.
    #[arg(long)]
    pub validation: bool,
    /// Where normals and radii are estimated when the method reads them: `auto` on the GPU
    /// unless the device is a CPU implementation (lavapipe).
    #[arg(long, value_enum, default_value_t = EstimateOn::Auto)]
    pub estimate_on: EstimateOn,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub stream: StreamArgs,
}

/// Where timed frames are written (`render`, and `view --path`).
#[derive(Args, Debug, Default)]
pub struct TimingOutputArgs {
    /// Write per-pass GPU timings as JSON: run metadata, every measured frame's milliseconds
    /// per pass, and each pass's median with its bootstrap 95 % interval.
    #[arg(long, value_name = "JSON")]
    pub timings: Option<PathBuf>,
    /// Write the timed frames as a tidy CSV: frame, pass, ms (one row per frame and pass).
    #[arg(long, value_name = "CSV")]
    pub timings_csv: Option<PathBuf>,
    /// Write the timed frames as a trace (Chrome trace-event JSON) that Perfetto and
    /// chrome://tracing open: GPU passes on one track, recording and submission on another.
    #[arg(long, value_name = "JSON")]
    pub trace: Option<PathBuf>,
}

impl TimingOutputArgs {
    pub fn outputs(&self) -> timing::Outputs {
        timing::Outputs {
            json: self.timings.clone(),
            csv: self.timings_csv.clone(),
            trace: self.trace.clone(),
        }
    }
}

/// Which hidden point removal filters a render (`--visibility`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Visibility {
    /// The sector approximation (003 ch. 4; the full-sphere partition where the viewpoint is
    /// inside or near the bounding sphere).
    Hpr,
    /// Exact HPR (003 §2.1).
    HprExact,
}

impl Visibility {
    /// The algorithm deciding visibility.
    fn algorithm(self) -> Algorithm {
        match self {
            Self::Hpr => Algorithm::Sectors,
            Self::HprExact => Algorithm::Exact,
        }
    }
}

/// Streaming a COPC file or a virtual point cloud (`.vpc`; a path or an http(s) URL) by
/// view instead of loading it.
#[derive(Args, Debug, Clone)]
pub struct StreamArgs {
    /// Stream FILE (a COPC path or URL): read only the octree nodes the view needs, within
    /// the point and GPU budgets. URLs and `.vpc` files are always streamed.
    #[arg(long)]
    pub stream: bool,
    /// Streaming: points drawn per frame at most.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_POINT_BUDGET)]
    pub point_budget: u64,
    /// Streaming: GPU memory for the resident nodes, in bytes (K, M, G suffixes).
    #[arg(long, value_name = "BYTES", default_value = "1G", value_parser = parse_bytes)]
    pub gpu_budget: u64,
    /// Streaming: refine while a node's point spacing projects to more pixels than this.
    #[arg(long, value_name = "PX", default_value_t = DEFAULT_ERROR_PX)]
    pub error_px: f32,
    /// Streaming: render after N frames of refinement instead of when every node the view
    /// needs is resident.
    #[arg(long, value_name = "N")]
    pub refine_frames: Option<u32>,
    /// Streaming over HTTP: requests in flight at most (over every file of a `.vpc`).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_CONNECTIONS as u64,
          value_parser = clap::value_parser!(u64).range(1..=256))]
    pub http_connections: u64,
}

impl StreamArgs {
    /// Whether `file` is streamed.
    pub fn streams(&self, file: &std::path::Path) -> bool {
        let name = file.to_string_lossy();
        self.stream || crate::source::is_url(&name) || crate::copc::vpc::is_vpc(&name)
    }

    /// The streaming options for a method that needs normals and radii estimated with `k`
    /// neighbours (0: none) and, with `normal_field`, the splats' linear normal fields.
    pub fn options(&self, k: usize, normal_field: bool) -> StreamOptions {
        StreamOptions {
            point_budget: self.point_budget,
            gpu_bytes: self.gpu_budget,
            error_px: self.error_px,
            loader: LoaderOptions {
                k,
                normal_field,
                http: HttpOptions {
                    connections: self.http_connections as usize,
                    ..HttpOptions::default()
                },
                ..LoaderOptions::default()
            },
        }
    }
}

/// Parses a byte count with an optional K, M or G suffix (powers of 1024).
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last() {
        Some((i, 'k' | 'K')) => (&t[..i], 10),
        Some((i, 'm' | 'M')) => (&t[..i], 20),
        Some((i, 'g' | 'G')) => (&t[..i], 30),
        _ => (t, 0),
    };
    digits
        .parse::<u64>()
        .ok()
        .and_then(|n| n.checked_mul(1 << shift))
        .filter(|&n| n > 0)
        .ok_or_else(|| {
            format!("expected a positive byte count such as 512M or 2G, found \"{text}\"")
        })
}

impl RenderArgs {
    /// Whether frames are timed (`--timings`, `--timings-csv`, `--trace` or `--path`).
    fn timed(&self) -> bool {
        self.outputs.outputs().any() || self.path.is_some()
    }

    fn plan(&self) -> FramePlan {
        FramePlan {
            warmup: self.warmup,
            frames: self.frames,
            min_time_s: self.min_time,
        }
    }
}

/// Timings written by `render --timings`: the study and what this run adds to it.
#[derive(Serialize)]
struct Timings {
    #[serde(flatten)]
    study: Study,
    points_per_second: f64,
    startup: Startup,
    /// With `--path`: the path time of each frame (the samples' order).
    #[serde(skip_serializing_if = "Option::is_none")]
    path_times: Option<Vec<f64>>,
}

/// Wall-clock seconds from the start of `surfel render` to its first finished frame.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
struct Startup {
    /// Parsing and preprocessing (normals, radii).
    load_s: f64,
    /// Of `load_s`, estimating normals and radii (0 when the method needs none or the file
    /// has them).
    estimate_s: f64,
    /// Where they were estimated: "gpu" or "cpu".
    estimate_on: &'static str,
    /// Vulkan instance and device.
    device_s: f64,
    /// Morton ordering, stream encoding and upload.
    upload_s: f64,
    /// Graph compilation and the first frame on the GPU.
    first_frame_s: f64,
    /// The sum: time to first pixel.
    first_pixel_s: f64,
}

pub(super) fn render(a: RenderArgs) -> Result<()> {
    if a.list_methods {
        for m in METHODS {
            println!("{}", m.name);
        }
        return Ok(());
    }
    let file = a.file.clone().context("FILE is required")?;
    if a.stream.streams(&file) {
        return render_streamed(a, &file);
    }
    let config = MethodConfig::parse(&a.method)?;
    let (width, height) = Size::parse(&a.size).map_err(anyhow::Error::msg)?.pair();
    let settings = view_settings(&a.camera)?;
    let start = std::time::Instant::now();
    let mut lap = start;
    let mut since = || {
        let now = std::time::Instant::now();
        let s = (now - lap).as_secs_f64();
        lap = now;
        s
    };
    // The device first: normals and radii may be estimated on it.
    let ctx = context(a.validation)?;
    let device_s = since();
    let on_gpu = a.estimate_on.uses_gpu(&ctx);
    let gpu_estimate = |cloud: &mut Cloud, options: &preprocess::PreprocessOptions| {
        crate::knn_gpu::estimate(&ctx, cloud, options).map(drop)
    };
    let estimator: Estimator = if on_gpu {
        &gpu_estimate
    } else {
        &crate::scene::input::estimate_on_cpu
    };
    let (cloud, estimate_s) = compose::load(
        &file,
        &settings.inputs,
        &a.input.options(estimates(config.method, &settings)),
        estimator,
    )?;
    check_surfels(config.method, &cloud, &file)?;
    // The camera frames the whole cloud, also when only its visible points are rendered.
    let (centre, radius) = cloud.bounding_sphere().unwrap_or((glam::Vec3::ZERO, 1.0));
    let path = match &a.path {
        Some(file) => {
            let path = CameraPath::load(file)?;
            let up = settings.up(cloud.up);
            let cameras = path.cameras(&|pose| pose.camera(centre, radius, up, cloud.origin));
            Some((path, cameras))
        }
        None => None,
    };
    let camera = match &path {
        Some((_, cameras)) => cameras[0],
        None => settings.camera(centre, radius, cloud.up, cloud.origin),
    };
    let cloud = match a.visibility {
        Some(mode) => visible_only(
            &cloud,
            mode,
            HprView {
                camera,
                width,
                height,
            },
        )?,
        None => cloud,
    };
    let coloring = settings.coloring(&file, &cloud)?;
    let load_s = since();
    let options = config
        .method
        .upload_options(UploadOptions::colored(coloring));
    let (mut scene, info) = upload(&ctx, &cloud, &options)?;
    // The scene file's hidden classes need the class stream.
    if let Some(k) = crate::scene::clip::classification_field(&cloud)
        .filter(|_| !settings.filter.hidden.is_empty())
    {
        scene.streams.add_classes(
            &ctx,
            &cloud,
            k,
            crate::point_streams::upload::DEFAULT_CHUNK_BYTES,
        )?;
    }
    let upload_s = since();
    let mut renderer = Renderer::new(
        &ctx,
        &scene,
        info,
        &config,
        width,
        height,
        RendererOptions {
            readback: true,
            present: None,
            post: settings.post.for_readback(),
            pipeline_statistics: a.pipeline_stats,
            ..RendererOptions::default()
        },
    )?;
    renderer.set_filter(settings.filter.active(cloud.origin));
    if a.dump_graph {
        print!("{}", renderer.schedule());
    }
    let view = View {
        camera,
        lights: settings.lights,
        use_color: !a.camera.no_color,
        time: 0.0,
    };
    let first = renderer.render(&view, true)?;
    let first_frame_s = since();
    let startup = Startup {
        load_s,
        estimate_s,
        estimate_on: if on_gpu { "gpu" } else { "cpu" },
        device_s,
        upload_s,
        first_frame_s,
        first_pixel_s: (lap - start).as_secs_f64(),
    };
    let estimated = if estimate_s > 0.0 {
        let on = if on_gpu { "GPU" } else { "CPU" };
        format!(" of which normals and radii {estimate_s:.2} s on the {on}")
    } else {
        String::new()
    };
    eprintln!(
        "first pixel after {:.2} s (device {:.2} s, load {:.2} s{estimated}, upload {:.2} s, first frame {:.2} s)",
        startup.first_pixel_s, device_s, load_s, upload_s, first_frame_s
    );
    let timed = a.timed();
    let mut last_view = view.clone();
    if timed {
        let (series, plan, path_times) = match &path {
            Some((path, cameras)) => {
                let views: Vec<View> = cameras
                    .iter()
                    .map(|&camera| View {
                        camera,
                        ..view.clone()
                    })
                    .collect();
                let plan = FramePlan {
                    frames: path.frames,
                    min_time_s: 0.0,
                    ..a.plan()
                };
                // Warm-up frames show the path's first view; each timed frame the next one.
                let series = measure(&mut renderer, plan, |r, i| {
                    r.render(&views[i.unwrap_or(0)], false).map(drop)
                })?;
                last_view = views[views.len() - 1].clone();
                (series, plan, Some(path.times()))
            }
            None => {
                let series = measure(&mut renderer, a.plan(), |r, _| {
                    r.render(&view, false).map(drop)
                })?;
                (series, a.plan(), None)
            }
        };
        let meta = RunMeta::headless(&ctx, &config.label(), (width, height), info.points.into());
        let study = Study::new(meta, plan, &series);
        let median = study.frame.median_ms;
        let timings = Timings {
            points_per_second: if median > 0.0 {
                f64::from(info.points) / (median / 1000.0)
            } else {
                0.0
            },
            study,
            startup,
            path_times,
        };
        a.outputs
            .outputs()
            .write(&serde_json::to_value(&timings)?, &timings.study, &series)?;
    }
    // The frame to write: the first one, unless timed frames followed (then a fresh one of
    // the last view: a path's last frame).
    let mut frame = if timed {
        renderer.render(&last_view, true)?
    } else {
        first
    }
    .context("renderer returned no frame")?;
    drop(renderer);
    write_composited(&ctx, &mut frame, settings.post.background, &a.out)?;
    eprintln!(
        "{}: {} points, {} -> {}",
        file.display(),
        info.points,
        config.label(),
        a.out.display()
    );
    Ok(())
}

/// The points of `cloud` that `mode` finds visible in `view`, without faces; says how many.
fn visible_only(cloud: &Cloud, mode: Visibility, view: HprView) -> Result<Cloud> {
    let radius = crate::hpr::Radius::Density {
        spacing: crate::hpr::spacing(cloud),
    };
    let found = visible_points(cloud, &view, &Request::new(mode.algorithm(), radius))?;
    let v = found.visibility;
    let note = found.note;
    eprintln!(
        "{note}; {} of {} points visible",
        v.visible.len(),
        cloud.len()
    );
    let mut visible = crate::hpr::visible_cloud(cloud, &v);
    visible.faces = None;
    Ok(visible)
}

/// Iterations without any progress after which a streamed render gives up.
const STALL_ROUNDS: u32 = 600;

/// `surfel render --stream`: the nodes of the view streamed in until the view's choice is
/// resident (or `--refine-frames` frames), then one frame written.
fn render_streamed(a: RenderArgs, file: &std::path::Path) -> Result<()> {
    let config = MethodConfig::parse(&a.method)?;
    let (width, height) = Size::parse(&a.size).map_err(anyhow::Error::msg)?.pair();
    let settings = view_settings(&a.camera)?;
    if a.visibility.is_some() {
        bail!("--visibility reads the whole cloud; it cannot be combined with streaming");
    }
    let start = std::time::Instant::now();
    let ctx = context(a.validation)?;
    let location = file.to_string_lossy().into_owned();
    let renderer_options = RendererOptions {
        readback: true,
        present: None,
        post: settings.post.for_readback(),
        pipeline_statistics: a.pipeline_stats,
        ..RendererOptions::default()
    };
    let k = if config.method.needs_surfels {
        a.input.k
    } else {
        0
    };
    let mut streamed = StreamedScene::open(
        &ctx,
        &location,
        &a.stream.options(k, config.method.needs_normal_field),
        |root| settings.coloring(file, root),
        renderer_options.frames_in_flight,
    )?;
    let (centre, radius) = streamed.bounding_sphere();
    if a.path.is_some() {
        bail!("--path renders a loaded file; a streamed file (COPC, .vpc, URL) does not take it");
    }
    let camera = settings.camera(centre, radius, streamed.root.up, streamed.origin());
    let mut renderer = Renderer::new(
        &ctx,
        &streamed.scene,
        streamed.info,
        &config,
        width,
        height,
        renderer_options,
    )?;
    renderer.set_filter(settings.filter.active(streamed.origin()));
    if a.dump_graph {
        print!("{}", renderer.schedule());
    }
    let view = View {
        camera,
        lights: settings.lights,
        use_color: !a.camera.no_color,
        time: 0.0,
    };
    streamed.update(&camera, width, height)?;
    renderer.render_batches(&view, Some(streamed.batches()), false)?;
    let first_pixel_s = start.elapsed().as_secs_f64();
    let mut frames = 1u32;
    let mut stalled = 0;
    loop {
        for m in streamed.take_messages() {
            eprintln!("warning: {m}");
        }
        match a.stream.refine_frames {
            Some(n) if frames >= n => break,
            Some(_) => {}
            None if streamed.stable() => break,
            None => {
                // Nothing to draw until a worker finishes: wait for one.
                if streamed.wait(std::time::Duration::from_millis(100)) {
                    stalled = 0;
                } else {
                    stalled += 1;
                    if stalled >= STALL_ROUNDS {
                        bail!(
                            "{location}: streaming made no progress for {} s ({} nodes loading)",
                            STALL_ROUNDS / 10,
                            streamed.stats().loading
                        );
                    }
                }
            }
        }
        streamed.update(&camera, width, height)?;
        if a.stream.refine_frames.is_some() {
            renderer.render_batches(&view, Some(streamed.batches()), false)?;
            frames += 1;
        }
    }
    let refine_s = start.elapsed().as_secs_f64() - first_pixel_s;
    if a.timed() {
        let view_batches = streamed.batches().to_vec();
        let series = measure(&mut renderer, a.plan(), |r, _| {
            r.render_batches(&view, Some(&view_batches), false)
                .map(drop)
        })?;
        let points = streamed.file_points();
        let meta = RunMeta::headless(&ctx, &config.label(), (width, height), points);
        let study = Study::new(meta, a.plan(), &series);
        let frame = &study.frame;
        let stats = streamed.stats();
        let loader = stats.loader;
        let busy = loader.read_s + loader.decode_s + loader.prepare_s;
        let per_core = |s: f64| {
            if s > 0.0 {
                loader.points as f64 / s
            } else {
                0.0
            }
        };
        let mut report = serde_json::json!({
            "location": location,
            "file_points": streamed.file_points(),
            "width": width,
            "height": height,
            "point_budget": a.stream.point_budget,
            "gpu_budget_bytes": a.stream.gpu_budget,
            "pool_bytes": streamed.pool_bytes(),
            "selected_points": stats.selected_points,
            "drawn_points": stats.drawn_points,
            "selected_nodes": stats.selected_nodes,
            "bytes_read": stats.bytes_read,
            "tiles": streamed.tiles().iter().map(|t| serde_json::json!({
                "href": t.href,
                "points": t.points,
                "opened": t.file.is_some(),
                "failed": t.error.is_some(),
                "bytes_read": t.bytes_read(),
                "reads": t.reads(),
            })).collect::<Vec<_>>(),
            "first_pixel_s": first_pixel_s,
            "refine_s": refine_s,
            "max_rss_bytes": max_rss_bytes(),
            "decoded_nodes": loader.nodes,
            "decoded_points": loader.points,
            "read_s": loader.read_s,
            "decode_s": loader.decode_s,
            "prepare_s": loader.prepare_s,
            "decode_points_per_core_s": per_core(loader.decode_s),
            "load_points_per_core_s": per_core(busy),
        });
        if let (Some(fields), serde_json::Value::Object(base)) =
            (report.as_object_mut(), serde_json::to_value(&study)?)
        {
            fields.extend(base);
        }
        a.outputs.outputs().write(&report, &study, &series)?;
        eprintln!(
            "frame {:.3} ms; decode {:.2} M points/s per core, read + decode + prepare {:.2} M points/s per core",
            frame.median_ms,
            per_core(loader.decode_s) / 1e6,
            per_core(busy) / 1e6
        );
    }
    let mut frame = renderer
        .render_batches(&view, Some(streamed.batches()), true)?
        .context("renderer returned no frame")?;
    let stats = streamed.stats();
    drop(renderer);
    write_composited(&ctx, &mut frame, settings.post.background, &a.out)?;
    eprintln!(
        "first pixel after {first_pixel_s:.2} s; refined in {refine_s:.2} s: {} of {} selected points drawn from {} nodes, {:.1} MB read, {} -> {}",
        stats.drawn_points,
        stats.selected_points,
        stats.selected_nodes,
        stats.bytes_read as f64 / 1e6,
        config.label(),
        a.out.display()
    );
    Ok(())
}

/// The process's peak resident memory in bytes (`getrusage`), 0 where unknown.
fn max_rss_bytes() -> u64 {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage writes the struct it is given; RUSAGE_SELF is always valid.
    let ok = unsafe { libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) } == 0;
    if ok {
        // SAFETY: initialised by the successful call.
        let usage = unsafe { usage.assume_init() };
        u64::try_from(usage.ru_maxrss).unwrap_or(0) * 1024
    } else {
        0
    }
}

/// Composites `frame` over `background` and writes it to `out`, after failing on any
/// validation error the finished renderer left (call it once the renderer is dropped).
fn write_composited(
    ctx: &crate::gpu::Context,
    frame: &mut crate::frame::Frame,
    background: crate::post::Background,
    out: &std::path::Path,
) -> Result<()> {
    crate::post::composite(frame, background);
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    crate::frame::write_png(out, frame, crate::frame::Channels::Rgba)
        .with_context(|| format!("{}: cannot write PNG", out.display()))
}

//! `surfel render`: one method's frames of a file, headless, to a PNG and timings.

use std::path::PathBuf;

use anyhow::{bail, Context as _, Result};
use clap::Args;
use serde::Serialize;

use super::hpr::{visible_points, SectorOptions, Visibility};
use super::{check_surfels, context, estimates, view_settings, CameraArgs, InputArgs};
use crate::estimate::EstimateOn;
use crate::frame::Size;
use crate::gpu::ScopeStats;
use crate::methods::{MethodConfig, METHODS};
use crate::render::{Extras, Renderer, View};
use crate::scene::compose;
use crate::scene::preprocess;
use crate::scene::{Cloud, Estimator};
use crate::upload::{upload, UploadOptions};

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
    /// Write per-pass GPU timings (median over --frames frames) as JSON.
    #[arg(long, value_name = "JSON")]
    pub timings: Option<PathBuf>,
    /// Timed frames (after 3 warm-up frames) for --timings.
    #[arg(long, default_value_t = 20)]
    pub frames: u32,
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
}

/// Timings written by `render --timings`.
#[derive(Serialize)]
struct Timings<'a> {
    device: &'a str,
    driver: &'a str,
    method: String,
    width: u32,
    height: u32,
    points: u32,
    frames: u32,
    passes: Vec<ScopeStats>,
    frame: ScopeStats,
    points_per_second: f64,
    startup: Startup,
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
    let file = a.file.context("FILE is required")?;
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
        crate::estimate::estimate(&ctx, cloud, options).map(drop)
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
    let camera = settings.camera(centre, radius, cloud.up);
    let cloud = match a.visibility {
        Some(mode) => {
            let radius = crate::hpr::Radius::Density {
                spacing: crate::hpr::spacing(&cloud),
            };
            let view = crate::eval::hpr_view::HprView {
                camera,
                width,
                height,
            };
            let options = SectorOptions::default();
            let found = visible_points(&cloud, &view, mode, radius, options)?;
            let v = found.visibility;
            let note = found.note;
            eprintln!(
                "{note}; {} of {} points visible",
                v.visible.len(),
                cloud.len()
            );
            let mut visible = crate::hpr::visible_cloud(&cloud, &v);
            visible.faces = None;
            visible
        }
        None => cloud,
    };
    let coloring = settings.coloring(&file, &cloud)?;
    let load_s = since();
    let options = config
        .method
        .upload_options(UploadOptions::colored(coloring));
    let (scene, info) = upload(&ctx, &cloud, &options)?;
    let upload_s = since();
    let mut renderer = Renderer::new(
        &ctx,
        &scene,
        info,
        &config,
        width,
        height,
        Extras {
            readback: true,
            present: None,
            post: settings.post.for_readback(),
            ..Extras::default()
        },
    )?;
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
    if let Some(path) = &a.timings {
        for _ in 0..3 {
            renderer.render(&view, false)?;
        }
        renderer.clear_timings();
        for _ in 0..a.frames.max(1) {
            renderer.render(&view, false)?;
        }
        let (passes, frame) = renderer.timings();
        let timings = Timings {
            device: &ctx.caps.device_name,
            driver: &ctx.caps.driver,
            method: config.label(),
            width,
            height,
            points: info.points,
            frames: a.frames.max(1),
            points_per_second: if frame.median_ms > 0.0 {
                info.points as f64 / (frame.median_ms / 1000.0)
            } else {
                0.0
            },
            passes,
            frame,
            startup,
        };
        std::fs::write(path, serde_json::to_string_pretty(&timings)?)
            .with_context(|| format!("{}: cannot write timings", path.display()))?;
        for p in &timings.passes {
            eprintln!(
                "{:<24} {:>9.3} ms (IQR {:.3})",
                p.name, p.median_ms, p.spread_ms
            );
        }
        eprintln!("{:<24} {:>9.3} ms", "frame", timings.frame.median_ms);
    }
    // The frame to write: the first one, unless timed frames followed (then a fresh one).
    let mut frame = if a.timings.is_some() {
        renderer.render(&view, true)?
    } else {
        first
    }
    .context("renderer returned no frame")?;
    crate::post::composite(&mut frame, settings.post.background);
    drop(renderer);
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    image::save_buffer(
        &a.out,
        bytemuck::cast_slice(&frame.color),
        width,
        height,
        image::ExtendedColorType::Rgba8,
    )
    .with_context(|| format!("{}: cannot write PNG", a.out.display()))?;
    eprintln!(
        "{}: {} points, {} -> {}",
        file.display(),
        info.points,
        config.label(),
        a.out.display()
    );
    Ok(())
}

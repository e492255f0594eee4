//! `surfel bench`: runs a sweep (models x methods x parameters x resolutions x poses x lights,
//! point counts and stress values) on the GPU, scores every frame against the ground truth and
//! writes `results.json`, `results.csv` and the charts.
//!
//! Timed frames are rendered without readback; the scored frame is a separate frame with
//! readback, so neither readback nor PNG encoding is inside a timing. Warm-up lasts at least
//! the sweep's `warmup` frames and [`WARMUP_MIN_SECONDS`] (caches, pipeline compilation and
//! lavapipe's thread pool settle; with 5 frames alone one configuration measured 20.7 and
//! 10.4 ms in two runs); records keep the median and the interquartile range of the timed
//! frames.

use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context as _, Result};
use glam::Vec3;

use super::config::{BenchConfig, Job, PoseSpec, StressKind};
use super::metrics;
use super::results::{PassTiming, Record, Results, Skipped, REFERENCE_METHOD};
use super::stress;
use super::timing::Invocations;
use super::Frame;
use crate::gpu::Context;
use crate::gpu_scene::{upload, GpuScene, SceneInfo, UploadOptions};
use crate::methods::MethodConfig;
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::{lights, load_prepared, sample, Camera, Cloud, LoadOptions, Pose};

/// Shortest warm-up per job, in seconds of wall time (at most [`WARMUP_MAX_FRAMES`] frames).
pub const WARMUP_MIN_SECONDS: f64 = 0.5;
/// Warm-up frames beyond which the time floor no longer extends the warm-up.
const WARMUP_MAX_FRAMES: u32 = 200;

/// Frames of the slow orbit used for the temporal-flicker metric, and the step between them.
const FLICKER_FRAMES: usize = 4;
const FLICKER_STEP_DEG: f32 = 0.5;
/// Seed of the cloud-side stress transforms and of mesh resampling (results are reproducible).
const SEED: u64 = 7;

/// A scene on the GPU plus what the jobs need to know about it.
struct Loaded {
    cloud: Cloud,
    gpu: GpuScene,
    info: SceneInfo,
}

/// Uploads `cloud` with `options` (what the sweep's methods read beyond the streams).
fn load_gpu(ctx: &Arc<Context>, cloud: Cloud, options: UploadOptions) -> Result<Loaded> {
    let (gpu, info) = upload(ctx, &cloud, &options)?;
    Ok(Loaded { cloud, gpu, info })
}

/// The camera of a job: its pose, or the pose changed by a camera-side stress.
fn job_camera(job: &Job, info: &SceneInfo, spacing: f32) -> Camera {
    let base = match &job.pose.pose {
        PoseSpec::Default => info.up.default_pose(),
        PoseSpec::Orbit {
            azimuth,
            elevation,
            distance,
        } => Pose::Orbit {
            orbit: [*azimuth, *elevation],
            distance: *distance,
        },
        PoseSpec::LookAt { eye, target } => Pose::LookAt {
            eye: eye.map(f64::from),
            target: target.map(f64::from),
        },
        // The path's first frame is its first key's pose.
        PoseSpec::Path { path, .. } => path.keys[0].camera,
    };
    let camera = base.camera(info.centre, info.radius, info.up, info.origin);
    let Some((kind, value)) = job.stress else {
        return camera;
    };
    let value = value as f32;
    let dir = (camera.eye - camera.target).normalize_or(Vec3::Z);
    let at_distance = |d: f32| Camera {
        eye: camera.target + dir * d,
        ..camera
    };
    match kind {
        // Tilt the view by `value` degrees away from the pose's direction (for a surface facing
        // the pose's camera, the angle between view and surface normal), at the pose's distance.
        StressKind::Grazing => {
            let (az, el, distance) = match base {
                Pose::Orbit { orbit, distance } => (orbit[0], orbit[1], distance),
                Pose::LookAt { .. } => (0.0, 0.0, 1.0),
            };
            Camera::orbit_about(
                info.up,
                info.centre,
                info.radius,
                az,
                (el + value).min(89.0),
                distance,
            )
        }
        // Move in until the mean point spacing covers `value` pixels.
        StressKind::Magnification => {
            let d =
                spacing * job.height as f32 / (2.0 * (camera.fov_y * 0.5).tan() * value.max(1e-3));
            at_distance(d.max(camera.near * 2.0))
        }
        StressKind::Inside => at_distance(value * info.radius),
        StressKind::Subsample | StressKind::Noise | StressKind::Nonuniform => camera,
    }
}

/// The camera of every frame along a job's camera path (`None` for a fixed pose, and for a
/// camera-side stress, which changes the first frame's pose and is timed there).
fn job_path(job: &Job, info: &SceneInfo) -> Option<(Vec<Camera>, Vec<f64>)> {
    let PoseSpec::Path { path, .. } = &job.pose.pose else {
        return None;
    };
    if job.stress.is_some_and(|(kind, _)| !cloud_side(kind)) {
        return None;
    }
    let cameras = path.cameras(&|pose| pose.camera(info.centre, info.radius, info.up, info.origin));
    Some((cameras, path.times()))
}

/// Whether a stress changes the cloud (otherwise it changes the camera).
fn cloud_side(kind: StressKind) -> bool {
    matches!(
        kind,
        StressKind::Subsample | StressKind::Noise | StressKind::Nonuniform
    )
}

/// Applies a cloud-side stress to `cloud`.
fn stressed(cloud: &Cloud, kind: StressKind, value: f64) -> Result<Cloud> {
    Ok(match kind {
        StressKind::Subsample => stress::subsample(cloud, value, SEED)?,
        StressKind::Noise => stress::noise(cloud, value, SEED)?,
        StressKind::Nonuniform => stress::nonuniform(cloud, value, SEED)?,
        StressKind::Grazing | StressKind::Magnification | StressKind::Inside => cloud.clone(),
    })
}

/// Median point spacing from the radii (the density form radius is ~0.89 x the spacing).
fn point_spacing(cloud: &Cloud, fallback: f32) -> f32 {
    let Some(r) = &cloud.radii else {
        return fallback;
    };
    let mut r: Vec<f32> = r
        .iter()
        .copied()
        .filter(|x| x.is_finite() && *x > 0.0)
        .collect();
    if r.is_empty() {
        return fallback;
    }
    let mid = r.len() / 2;
    let (_, m, _) = r.select_nth_unstable_by(mid, f32::total_cmp);
    *m / 0.89
}

struct Timed {
    passes: Vec<PassTiming>,
    frame_ms: (f64, f64),
    /// Every measured frame's GPU milliseconds.
    frame_samples: Vec<f64>,
    /// Each pass's median shader invocations (with `pipeline_stats`).
    invocations: Vec<Invocations>,
    frames: Vec<Frame>,
    /// The first (scored) view's samples per level, for methods that count them
    /// (`Renderer::samples_per_level`).
    projected_per_level: Option<Vec<u64>>,
}

/// Renders `views` once each with readback after the timed frames: `warmup` + `measured`
/// frames of the first view, or with a camera path (`path`, one view per path frame) the
/// warm-up at its first view and one timed frame per path frame.
fn run_method(
    ctx: &Arc<Context>,
    scene: &Loaded,
    config: &MethodConfig,
    job: &Job,
    views: &[View],
    path: &[View],
) -> Result<Timed> {
    // A fixed pose repeats the first view; a path shows each of its views once.
    let timed_views = if path.is_empty() { &views[..1] } else { path };
    let measured = if path.is_empty() {
        job.frames.measured.max(1) as usize
    } else {
        path.len()
    };
    let view = |i: usize| &timed_views[i.min(timed_views.len() - 1)];
    let mut r = Renderer::new(
        ctx,
        &scene.gpu,
        scene.info,
        config,
        job.width,
        job.height,
        RendererOptions {
            readback: true,
            present: None,
            pipeline_statistics: job.frames.pipeline_stats,
            ..RendererOptions::default()
        },
    )?;
    let start = std::time::Instant::now();
    let mut warmed = 0;
    while warmed < job.frames.warmup
        || (warmed < WARMUP_MAX_FRAMES
            && job.frames.warmup > 0
            && start.elapsed().as_secs_f64() < WARMUP_MIN_SECONDS)
    {
        r.render(view(0), false)?;
        warmed += 1;
    }
    r.clear_timings();
    for i in 0..measured {
        r.render(view(i), false)?;
    }
    let (scopes, frame) = r.timings();
    let series = r.timing_series();
    let invocations = Invocations::of(&series);
    let mut projected_per_level = None;
    let mut frames = Vec::with_capacity(views.len());
    for (i, v) in views.iter().enumerate() {
        frames.push(r.render(v, true)?.context("no frame read back")?);
        if i == 0 {
            projected_per_level = r.samples_per_level().map(<[u64]>::to_vec);
        }
    }
    Ok(Timed {
        passes: scopes
            .into_iter()
            .zip(series.gpu.scopes)
            .map(|(s, (_, samples_ms))| PassTiming {
                name: s.name,
                median_ms: s.median_ms,
                iqr_ms: s.iqr_ms,
                samples_ms,
            })
            .collect(),
        frame_ms: (frame.median_ms, frame.iqr_ms),
        frame_samples: series.gpu.frame,
        invocations,
        frames,
        projected_per_level,
    })
}

/// Everything a sweep run produces.
pub struct BenchOutput {
    pub results: Results,
    pub json: PathBuf,
    pub csv: PathBuf,
    pub charts: Vec<PathBuf>,
}

/// Runs every job of `config` and writes results and charts into `out_dir`.
pub fn run(
    ctx: &Arc<Context>,
    config: &BenchConfig,
    out_dir: &Path,
    log: bool,
) -> Result<BenchOutput> {
    config.check_models()?;
    if let Some(available) = sample::available_memory() {
        config.check_memory(available)?;
    }
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("{}: cannot create", out_dir.display()))?;
    let mut results = Results {
        device: ctx.caps.device_name.clone(),
        driver: ctx.caps.driver.clone(),
        created: created_now(),
        records: Vec::new(),
        skipped: Vec::new(),
    };
    let mut models: HashMap<PathBuf, Loaded> = HashMap::new();
    let mut variants: HashMap<(PathBuf, String), Loaded> = HashMap::new();
    let mut truths: HashMap<String, Vec<Frame>> = HashMap::new();
    let jobs = config.jobs();
    let options = jobs
        .iter()
        .filter_map(|j| crate::methods::find(&j.method).ok())
        .fold(UploadOptions::default(), |o, m| m.upload_options(o));
    let use_color = config.color;
    for (i, job) in jobs.iter().enumerate() {
        let truth_path = job.model.truth.as_ref().unwrap_or(&job.model.path).clone();
        for path in [&job.model.path, &truth_path] {
            if let Entry::Vacant(slot) = models.entry(path.clone()) {
                let cloud = load_prepared(path, &LoadOptions::default())
                    .with_context(|| format!("{}, model {:?}", config.origin, job.model.name))?;
                slot.insert(load_gpu(ctx, cloud, options)?);
            }
        }
        let original = &models[&job.model.path];
        // The ground truth's mesh and framing (the model itself unless `truth` names another).
        let reference = &models[&truth_path];
        // The scene the method renders: the model, a resampled copy, or a stressed copy.
        let variant_key = match (job.points, job.stress) {
            (Some(n), _) => Some(format!("points={n}")),
            (None, Some((kind, v))) if cloud_side(kind) => Some(format!("{}={v}", kind.as_str())),
            _ => None,
        };
        if let Some(key) = &variant_key {
            if let Entry::Vacant(slot) = variants.entry((job.model.path.clone(), key.clone())) {
                let cloud = match (job.points, job.stress) {
                    (Some(n), _) => sample::sample_mesh(&original.cloud, n as usize, SEED)
                        .with_context(|| {
                            format!("{}: resampling to {n} points", job.model.path.display())
                        })?,
                    (_, stress) => {
                        let (kind, v) = stress.context("variant without a stress")?;
                        stressed(&original.cloud, kind, v)?
                    }
                };
                slot.insert(load_gpu(ctx, cloud, options)?);
            }
        }
        let scene = match &variant_key {
            Some(key) => &variants[&(job.model.path.clone(), key.clone())],
            None => original,
        };
        let params: Vec<String> = job.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let spec = if params.is_empty() {
            job.method.clone()
        } else {
            format!("{}:{}", job.method, params.join(","))
        };
        let config = MethodConfig::parse(&spec)?;
        let skip_reason = if config.method.needs_faces && scene.gpu.indices.is_none() {
            Some(format!(
                "method '{}' needs triangle faces; this {} has none",
                config.method.name,
                if variant_key.is_some() {
                    "resampled or stressed cloud"
                } else {
                    "model"
                }
            ))
        } else {
            config.method.unsupported(&ctx.caps)
        };
        if let Some(reason) = skip_reason {
            let skipped = Skipped {
                model: job.model.name.clone(),
                method: config.label(),
                width: job.width,
                height: job.height,
                variant: variant_key.clone().unwrap_or_default(),
                reason,
            };
            eprintln!(
                "[{}/{}] skipped {} {} {}x{}{}: {}",
                i + 1,
                jobs.len(),
                skipped.model,
                skipped.method,
                skipped.width,
                skipped.height,
                variant_key.map_or(String::new(), |v| format!(" {v}")),
                skipped.reason
            );
            results.skipped.push(skipped);
            continue;
        }
        let spacing = point_spacing(&scene.cloud, scene.info.radius / 100.0);
        let camera = job_camera(job, &reference.info, spacing);
        let lights = lights::sweep(job.lights, reference.info.radius);
        let baseline = job.points.is_none() && job.stress.is_none();
        let view_at = |step: usize| {
            let mut c = camera;
            if step > 0 {
                let offset = c.eye - c.target;
                // The slow orbit turns about the data's up axis, like the viewer's drag.
                let rot = glam::Quat::from_axis_angle(
                    reference.info.up.vector(),
                    (FLICKER_STEP_DEG * step as f32).to_radians(),
                );
                c.eye = c.target + rot * offset;
            }
            View {
                camera: c,
                lights: lights.clone(),
                use_color,
                time: 0.0,
            }
        };
        let steps = if baseline { FLICKER_FRAMES } else { 1 };
        let views: Vec<View> = (0..steps).map(view_at).collect();
        if log {
            eprintln!(
                "[{}/{}] {} {} {}x{} {}",
                i + 1,
                jobs.len(),
                job.model.name,
                config.label(),
                job.width,
                job.height,
                job.stress
                    .map_or(String::new(), |(k, v)| format!("{}={v}", k.as_str()))
            );
        }
        let (path_views, path_times) = match job_path(job, &reference.info) {
            Some((cameras, times)) => (
                cameras
                    .into_iter()
                    .map(|camera| View {
                        camera,
                        ..views[0].clone()
                    })
                    .collect(),
                times,
            ),
            None => (Vec::new(), Vec::new()),
        };
        let timed = run_method(ctx, scene, &config, job, &views, &path_views)?;
        for f in &timed.frames {
            let report = metrics::check_finite(f)?;
            if !report.is_clean() {
                anyhow::bail!(
                    "{}: non-finite pixels in {}: {report:?}",
                    job.model.name,
                    config.label()
                );
            }
        }
        // Ground truth: the original mesh with the same camera, size and lights, rendered once
        // per distinct view set (methods and parameters share it).
        let mut scores = metrics::Scores::default();
        if reference.gpu.indices.is_some() {
            let camera_stress = job.stress.filter(|(k, _)| !cloud_side(*k));
            let key = format!(
                "{}|{}x{}|{}|{}|{camera_stress:?}|{steps}",
                truth_path.display(),
                job.width,
                job.height,
                job.pose.name,
                job.lights
            );
            if let Entry::Vacant(slot) = truths.entry(key.clone()) {
                let gt_job = Job {
                    frames: super::config::FrameCounts {
                        warmup: 0,
                        measured: 1,
                        pipeline_stats: false,
                    },
                    ..job.clone()
                };
                let gt = MethodConfig::parse(REFERENCE_METHOD)?;
                slot.insert(run_method(ctx, reference, &gt, &gt_job, &views, &[])?.frames);
            }
            let truth = &truths[&key];
            scores = metrics::score(&timed.frames[0], &truth[0])?;
            if baseline {
                scores.flicker = metrics::temporal_flicker(&timed.frames, truth)?;
            }
        }
        let frame_ms = timed.frame_ms.0;
        // Level of detail projects the samples it counted per level; the others every point.
        let projected_per_level = timed.projected_per_level.unwrap_or_default();
        let samples = if config.method.needs_lod {
            projected_per_level.iter().sum()
        } else {
            u64::from(scene.info.points)
        };
        results.records.push(Record {
            model: job.model.name.clone(),
            points: u64::from(scene.info.points),
            method: job.method.clone(),
            params: job.params.clone(),
            width: job.width,
            height: job.height,
            pose: job.pose.name.clone(),
            distance: job.pose.pose.distance(),
            lights: job.lights,
            stress: job.stress.map(|(k, _)| k.as_str().to_string()),
            stress_value: job.stress.map(|(_, v)| v),
            device: results.device.clone(),
            driver: results.driver.clone(),
            passes: timed.passes,
            frame_ms_median: frame_ms,
            frame_ms_iqr: timed.frame_ms.1,
            frame_samples_ms: timed.frame_samples.clone(),
            path_times,
            invocations: timed.invocations.clone(),
            points_per_second: if frame_ms > 0.0 {
                f64::from(scene.info.points) / (frame_ms / 1000.0)
            } else {
                0.0
            },
            projected_points: Some(samples),
            projected_per_level,
            scores,
        });
    }
    if log {
        eprintln!(
            "{} jobs: {} measured, {} skipped",
            jobs.len(),
            results.records.len(),
            results.skipped.len()
        );
    }
    let json = out_dir.join("results.json");
    let csv = out_dir.join("results.csv");
    results.write_json(&json)?;
    results.write_csv(&csv)?;
    let charts = super::charts::write_charts(&results, &out_dir.join("charts"))?;
    Ok(BenchOutput {
        results,
        json,
        csv,
        charts,
    })
}

/// The current UTC time as RFC 3339 (civil-from-days conversion; no time-zone database).
fn created_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

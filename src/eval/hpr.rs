//! The HPR study (`surfel hpr-study`): visible points against k (003
//! Fig. 5.1), precision, recall and F1 of the approximation against exact HPR and of both
//! against true visibility (the mesh's depth buffer), per-pass GPU time against the number of
//! points (sort-free and sorted), the R and noise sweeps, and the partial reconstruction at
//! 900 x 900 (003 Table 5.3). Writes `report.md`, `results.json` and charts.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::eval::hpr_view::{mesh_visibility, render_once, HprView};
use crate::gpu::Context;
use crate::gpu_scene::{upload, UploadOptions};
use crate::hpr::approx::{self, Params, Propagation};
use crate::hpr::{agreement, exact, spacing, Radius};
use crate::methods::hpr::{evaluate, Settings};
use crate::methods::MethodConfig;
use crate::render::{Renderer, RendererOptions, View};
use crate::scene::Cloud;

/// The scenes the evaluations run HPR on keep their bounding sphere between evaluations.
const HPR_UPLOAD: UploadOptions = UploadOptions {
    segment_points: None,
    chunk_bytes: crate::point_streams::upload::DEFAULT_CHUNK_BYTES,
    coloring: None,
    lod: false,
    normal_field: false,
    hpr: true,
};

/// Adaptive propagation as the study runs it: at most 64 rounds.
const ADAPTIVE: Propagation = Propagation::Adaptive { max_rounds: 64 };

/// What the study runs.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Models: (name, path).
    pub models: Vec<(String, PathBuf)>,
    /// The mesh the point-count series samples.
    pub sampled: PathBuf,
    /// Point counts of the time series.
    pub counts: Vec<usize>,
    /// The view's size.
    pub size: (u32, u32),
    /// GPU frames timed per configuration (after two warm-up frames).
    pub frames: u32,
}

/// One measured configuration.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Row {
    pub model: String,
    pub points: usize,
    pub what: String,
    pub sqrt_k: u32,
    pub visible: usize,
    pub rounds: u32,
    /// Against exact HPR at the same R.
    pub exact: (f64, f64, f64),
    /// Against true visibility.
    pub truth: Option<(f64, f64, f64)>,
    /// CPU seconds (exact or the CPU reference), single run.
    pub cpu_s: Option<f64>,
    /// GPU milliseconds of the HPR passes (median over the timed frames) and per pass.
    pub gpu_ms: Option<f64>,
    pub passes: Vec<(String, f64)>,
    /// Sector occupancy rows: the fractions of the k sectors holding a point and holding a
    /// distinct extreme after adaptive propagation.
    pub occupancy: Option<(f64, f64)>,
}

/// 003 Table 5.2: per model, the points, about how many are visible, and frames per second of
/// exact HPR, the CPU approximation and the GPU approximation with its m.
const THESIS_TABLE_5_2: [(&str, u32, u32, f64, f64, f64, u32); 4] = [
    ("Bimba", 74_764, 27_000, 2.0, 5.0, 50.0, 3),
    ("Armadillo", 172_974, 63_000, 1.0, 2.0, 25.0, 3),
    ("Dragon", 437_645, 150_000, 0.42, 0.28, 2.3, 10),
    ("Buddha", 719_560, 250_000, 0.30, 0.18, 1.7, 6),
];

/// 003 Table 5.3: the partial reconstruction at 900 × 900: model, points, √k, m, frames per
/// second.
const THESIS_TABLE_5_3: [(&str, u32, u32, u32, f64); 4] = [
    ("Bimba", 74_764, 923, 3, 50.0),
    ("Armadillo", 172_974, 1269, 3, 25.0),
    ("Buddha", 719_560, 678, 3, 25.0),
    ("Asian Dragon", 3_609_455, 906, 1, 11.0),
];

/// The thesis model a study model stands in for (by name: bunny for Bimba, the others by
/// their own names; the sampled dragon mesh for the Asian Dragon).
fn thesis_model(name: &str) -> Option<&'static str> {
    let name = name.to_lowercase();
    [
        ("bunny", "Bimba"),
        ("armadillo", "Armadillo"),
        ("dragon", "Dragon"),
        ("buddha", "Buddha"),
    ]
    .into_iter()
    .find(|(ours, _)| name.contains(ours))
    .map(|(_, theirs)| theirs)
}

/// The share of exact HPR's visible count at which the approximation counts as having reached
/// it (the thesis chose k for "approximately the same number of visible points").
const REACHED: f64 = 0.99;

/// The √k of the Table 5.2 search: 64 to 4096 in steps of 2^(1/4).
fn search_sqrt_ks() -> Vec<u32> {
    (0..=24)
        .map(|i| (64.0 * 2f64.powf(f64::from(i) / 4.0)).round() as u32)
        .collect()
}

/// The points of the sampled dragon that stand in for the Asian Dragon in Table 5.3.
const ASIAN_DRAGON_POINTS: usize = 3_609_455;

/// The eye of the study's view of `cloud`: three bounding-sphere radii from the centre along
/// (0.5, 0.3, 0.81) (the CPU report's pose).
fn eye_of(cloud: &Cloud) -> Vec3 {
    let (c, r) = cloud.bounding_sphere().unwrap_or((Vec3::ZERO, 1.0));
    c + Vec3::new(0.5, 0.3, 0.81).normalize() * 3.0 * r
}

fn label(p: Propagation) -> String {
    match p {
        Propagation::Adaptive { .. } => "adaptive".into(),
        // An even m gathers the centred (m + 1) × (m + 1) window.
        Propagation::Fixed(m) if m % 2 == 0 => format!("fixed m = {m} ({0}x{0})", m + 1),
        Propagation::Fixed(m) => format!("fixed {m}x{m}"),
    }
}

/// The method configuration that runs `propagation` in the frame loop.
fn method(sqrt_k: u32, radius_factor: f64, propagation: Propagation, sort: bool) -> String {
    let (m, rounds) = match propagation {
        Propagation::Adaptive { max_rounds } => (0, max_rounds),
        Propagation::Fixed(m) => (m, 1),
    };
    format!(
        "hpr:sectors={sqrt_k},max_sectors={sqrt_k},m={m},rounds={rounds},radius={radius_factor},sort={},complete=0",
        u32::from(sort)
    )
}

/// Median GPU milliseconds of the `hpr.*` passes (and each) of `config` rendering `cloud`.
fn gpu_time(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    view: &HprView,
    config: &str,
    frames: u32,
) -> Result<(f64, Vec<(String, f64)>)> {
    let config = MethodConfig::parse(config)?;
    let (scene, info) = upload(
        ctx,
        cloud,
        &config.method.upload_options(Default::default()),
    )?;
    let mut renderer = Renderer::new(
        ctx,
        &scene,
        info,
        &config,
        view.width,
        view.height,
        // Readback keeps the passes (the graph culls passes whose results nothing uses).
        RendererOptions {
            readback: true,
            ..RendererOptions::default()
        },
    )?;
    let v = View {
        camera: view.camera,
        lights: vec![crate::scene::Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    for _ in 0..2 {
        renderer.render(&v, false)?;
    }
    renderer.clear_timings();
    for _ in 0..frames.max(1) {
        renderer.render(&v, false)?;
    }
    renderer.finish()?;
    let (passes, _) = renderer.timings();
    // Adaptive rounds that ran no workgroups still cost their (empty) dispatch and barrier:
    // every recorded round counts.
    let hpr: Vec<(String, f64)> = passes
        .iter()
        .filter(|p| {
            (p.name.starts_with("hpr.") && !p.name.starts_with("hpr.points."))
                || p.name.starts_with("sort.")
        })
        .map(|p| (p.name.clone(), p.median_ms))
        .collect();
    Ok((hpr.iter().map(|p| p.1).sum(), hpr))
}

/// The complete visible set of the GPU passes (flipping radius `r`, finest grid `side`) in
/// `view`, as indices of the file's order (`order`: stream index to file index), ascending.
fn complete_on_gpu(
    ctx: &Arc<Context>,
    scene: &crate::gpu_scene::GpuScene,
    view: &HprView,
    size: (u32, u32),
    (r, side): (f64, u32),
    order: &[u32],
) -> Result<Vec<u32>> {
    let mut s = Settings::grid(1, r, Propagation::Fixed(3), false);
    s.params.complete_side = side;
    s.extremes = false;
    let gpu = evaluate(
        ctx,
        scene,
        (view.camera.view(), view.proj()),
        size,
        &s,
        false,
    )?;
    let mut visible: Vec<u32> = gpu.visible.iter().map(|&i| order[i as usize]).collect();
    visible.sort_unstable();
    Ok(visible)
}

/// The CPU reference of the approximation (`approx::approximate`) with errors as `anyhow`.
fn approximate(
    points: &[DVec3],
    eye: Vec3,
    sqrt_k: u32,
    radius: f64,
    propagation: Propagation,
) -> Result<approx::Approx> {
    approx::approximate(
        points,
        eye.as_dvec3(),
        Params {
            sqrt_k,
            radius,
            propagation,
        },
    )
    .map_err(|e| anyhow::anyhow!("{e}"))
}

/// 003 Table 5.2 and Fig. 5.9 for one model (the model and point count left for the caller):
/// for adaptive propagation and fixed m = 3 and m = 10 (an 11 × 11 gather: the window is
/// centred, reach m / 2), the smallest √k of [`search_sqrt_ks`] at which the CPU
/// approximation finds [`REACHED`] of the points exact HPR finds (`exact_visible`), scored against
/// them and timed on the CPU and the GPU (√k 0: not reached by the largest); and at every √k
/// the sector occupancy (sectors holding a point; distinct extremes after adaptive
/// propagation).
fn thesis_rows(
    ctx: &Arc<Context>,
    (cloud, points): (&Cloud, &[DVec3]),
    (eye, view): (Vec3, &HprView),
    r: f64,
    exact_visible: &[u32],
    frames: u32,
) -> Result<Vec<Row>> {
    let factor = factor_of(cloud, r);
    let propagations = [ADAPTIVE, Propagation::Fixed(3), Propagation::Fixed(10)];
    let mut reached = [false; 3];
    let mut largest = [0usize; 3];
    let mut rows = Vec::new();
    for sqrt_k in search_sqrt_ks() {
        let k = f64::from(sqrt_k).powi(2);
        let own = approximate(points, eye, sqrt_k, r, Propagation::Fixed(1))?;
        let occupied = own.max.iter().filter(|&&m| m != u32::MAX).count() as f64 / k;
        for (i, &propagation) in propagations.iter().enumerate() {
            let adaptive = matches!(propagation, Propagation::Adaptive { .. });
            if reached[i] && !adaptive {
                continue;
            }
            let start = Instant::now();
            let ap = approximate(points, eye, sqrt_k, r, propagation)?;
            let cpu_s = start.elapsed().as_secs_f64();
            largest[i] = ap.visible.len();
            if adaptive {
                rows.push(Row {
                    what: "occupancy".into(),
                    sqrt_k,
                    visible: ap.visible.len(),
                    occupancy: Some((occupied, ap.visible.len() as f64 / k)),
                    ..Default::default()
                });
            }
            if !reached[i] && ap.visible.len() as f64 >= REACHED * exact_visible.len() as f64 {
                reached[i] = true;
                let config = method(sqrt_k, factor, propagation, false);
                let (gpu_ms, passes) = gpu_time(ctx, cloud, view, &config, frames)?;
                rows.push(Row {
                    what: format!("table 5.2: {}", label(propagation)),
                    sqrt_k,
                    visible: ap.visible.len(),
                    rounds: ap.rounds,
                    exact: agreement(&ap.visible, exact_visible),
                    cpu_s: Some(cpu_s),
                    gpu_ms: Some(gpu_ms),
                    passes,
                    ..Default::default()
                });
            }
        }
    }
    for (i, &propagation) in propagations.iter().enumerate() {
        if !reached[i] {
            rows.push(Row {
                what: format!("table 5.2: {}", label(propagation)),
                visible: largest[i],
                ..Default::default()
            });
        }
    }
    Ok(rows)
}

/// The partial reconstruction (`hpr-mesh`, √k and fixed m) of `cloud` in `view` against the
/// rendered `mesh`: coverage and depth agreement, and GPU time (the model left for the caller).
fn reconstruction_row(
    ctx: &Arc<Context>,
    (cloud, mesh): (&Cloud, &Cloud),
    view: &HprView,
    factor: f64,
    (sqrt_k, m): (u32, u32),
    frames: u32,
) -> Result<Row> {
    let config =
        format!("hpr-mesh:sectors={sqrt_k},max_sectors={sqrt_k},m={m},rounds=1,radius={factor}");
    let recon = render_once(cloud, view, &config)?;
    let reference = render_once(mesh, view, "mesh:samples=1")?;
    let (iou, depth) = coverage_agreement(&recon, &reference);
    let (gpu_ms, passes) = gpu_time(ctx, cloud, view, &config, frames)?;
    Ok(Row {
        points: cloud.len(),
        what: format!(
            "table 5.3: m = {m}, coverage IoU {iou:.4}, median relative depth error {depth:.5}"
        ),
        sqrt_k,
        gpu_ms: Some(gpu_ms),
        passes,
        ..Default::default()
    })
}

/// The radius factor (of the bounding box's diagonal, as the methods' `radius` takes it) equal
/// to `r`.
fn factor_of(cloud: &Cloud, r: f64) -> f64 {
    r / crate::hpr::diagonal(&cloud.positions)
}

/// Runs the study; returns the rows and writes nothing.
pub fn run(options: &StudyOptions) -> Result<Vec<Row>> {
    let ctx = Arc::new(Context::new(&crate::gpu::ContextOptions::from_env())?);
    let mut rows = Vec::new();
    for (name, path) in &options.models {
        let cloud = crate::scene::input::load_prepared(path, &Default::default())
            .with_context(|| path.display().to_string())?;
        let eye = eye_of(&cloud);
        let view = HprView::new(&cloud, eye, None, options.size);
        let radius = Radius::Density {
            spacing: spacing(&cloud),
        };
        let r = crate::hpr::flip_radius(&cloud.positions, eye, radius)?;
        let start = Instant::now();
        let truth_exact = exact(&cloud.positions, eye, radius)?;
        let exact_s = start.elapsed().as_secs_f64();
        let seen = if cloud.faces.is_some() {
            Some(mesh_visibility(&cloud, &view)?)
        } else {
            None
        };
        let score = |visible: &[u32]| {
            (
                agreement(visible, &truth_exact.visible),
                seen.as_ref().map(|s| agreement(visible, s)),
            )
        };
        let (e, t) = score(&truth_exact.visible);
        rows.push(Row {
            model: name.clone(),
            points: cloud.len(),
            what: "exact".into(),
            visible: truth_exact.visible.len(),
            exact: e,
            truth: t,
            cpu_s: Some(exact_s),
            ..Default::default()
        });
        let points: Vec<DVec3> = cloud.positions.iter().map(|p| p.as_dvec3()).collect();
        let sphere = approx::bounding_sphere(&points).context("no points")?;
        let from_view = approx::sqrt_k_for_view(sphere, eye.as_dvec3(), view.pixel_angle(), 4096);
        let (scene, _) = upload(&ctx, &cloud, &HPR_UPLOAD)?;
        let order = crate::point_streams::morton_order(&cloud.positions);
        let mut ks = vec![64, 128, 256, 512, 1024, 2048, from_view];
        ks.sort_unstable();
        ks.dedup();
        for &sqrt_k in &ks {
            for propagation in [ADAPTIVE, Propagation::Fixed(3), Propagation::Fixed(5)] {
                let start = Instant::now();
                approximate(&points, eye, sqrt_k, r, propagation)?;
                let cpu_s = start.elapsed().as_secs_f64();
                let s = Settings::grid(sqrt_k, r, propagation, false);
                let gpu = evaluate(
                    &ctx,
                    &scene,
                    (view.camera.view(), view.proj()),
                    options.size,
                    &s,
                    false,
                )?;
                let mut visible: Vec<u32> =
                    gpu.visible.iter().map(|&i| order[i as usize]).collect();
                visible.sort_unstable();
                let (e, t) = score(&visible);
                let config = method(sqrt_k, factor_of(&cloud, r), propagation, false);
                let (gpu_ms, passes) = gpu_time(&ctx, &cloud, &view, &config, options.frames)?;
                let note = if sqrt_k == from_view { " (view)" } else { "" };
                rows.push(Row {
                    model: name.clone(),
                    points: cloud.len(),
                    what: format!("{}{note}", label(propagation)),
                    sqrt_k,
                    visible: visible.len(),
                    rounds: gpu.state.rounds,
                    exact: e,
                    truth: t,
                    cpu_s: Some(cpu_s),
                    gpu_ms: Some(gpu_ms),
                    passes,
                    ..Default::default()
                });
            }
        }
        // The complete visible set (beyond 003) on the CPU and the GPU, at its default grid.
        let side = crate::hpr::complete_side(cloud.len());
        let start = Instant::now();
        let cpu = crate::hpr::complete(&cloud.positions, eye, radius, Some(side))?;
        let cpu_s = start.elapsed().as_secs_f64();
        let (e, t) = score(&cpu.visible);
        rows.push(Row {
            model: name.clone(),
            points: cloud.len(),
            what: "complete (CPU)".into(),
            sqrt_k: side,
            visible: cpu.visible.len(),
            exact: e,
            truth: t,
            cpu_s: Some(cpu_s),
            ..Default::default()
        });
        let visible = complete_on_gpu(&ctx, &scene, &view, options.size, (r, side), &order)?;
        let (e, t) = score(&visible);
        let config = format!("hpr:radius={},complete=1", factor_of(&cloud, r));
        let (gpu_ms, passes) = gpu_time(&ctx, &cloud, &view, &config, options.frames)?;
        rows.push(Row {
            model: name.clone(),
            points: cloud.len(),
            what: "complete (GPU)".into(),
            sqrt_k: side,
            visible: visible.len(),
            exact: e,
            truth: t,
            gpu_ms: Some(gpu_ms),
            passes,
            ..Default::default()
        });
        if thesis_model(name).is_some() {
            rows.extend(thesis_rows(
                &ctx,
                (&cloud, &points),
                (eye, &view),
                r,
                &truth_exact.visible,
                options.frames,
            )?);
        }
        // R sweep (factors of the diameter) with exact HPR and the view's approximation.
        let sweep = |positions: &[Vec3], radius: Radius, what: &str| -> Result<Vec<Row>> {
            sweep_rows(positions, eye, radius, from_view, seen.as_deref(), what)
        };
        for f in [100.0, 1_000.0, 10_000.0, 30_000.0] {
            let what = format!("R sweep: {{}}, R = {f} x diameter");
            rows.extend(sweep(&cloud.positions, Radius::Factor(f), &what)?);
        }
        // Noise sweep: Gaussian offsets (σ in sample spacings) against the clean mesh's
        // visibility, R from the density of the clean cloud.
        if seen.is_some() {
            let radius = Radius::Density {
                spacing: spacing(&cloud),
            };
            for sigma in [0.25, 0.5, 1.0, 2.0] {
                let noisy = with_noise(&cloud, sigma * spacing(&cloud) as f32, 7);
                let what = format!("noise: {{}}, sigma = {sigma} spacing");
                rows.extend(sweep(&noisy.positions, radius, &what)?);
            }
        }
        for r in rows.iter_mut().filter(|r| r.model.is_empty()) {
            r.model = name.clone();
            r.points = cloud.len();
        }
        // The partial reconstruction at the thesis' √k and m (003 Table 5.3).
        let thesis = thesis_model(name)
            .and_then(|m| THESIS_TABLE_5_3.iter().find(|t| t.0 == m))
            .filter(|_| cloud.faces.is_some());
        if let Some(&(_, _, sqrt_k, m, _)) = thesis {
            let mut row = reconstruction_row(
                &ctx,
                (&cloud, &cloud),
                &view,
                factor_of(&cloud, r),
                (sqrt_k, m),
                options.frames,
            )?;
            row.model = name.clone();
            rows.push(row);
        }
        // The partial reconstruction at the view's √k: hpr-mesh against the mesh.
        if cloud.faces.is_some() {
            let config = format!(
                "hpr-mesh:sectors={from_view},max_sectors={from_view},radius={}",
                factor_of(&cloud, r)
            );
            let recon = render_once(&cloud, &view, &config)?;
            let mesh = render_once(&cloud, &view, "mesh:samples=1")?;
            let (iou, depth) = coverage_agreement(&recon, &mesh);
            let (gpu_ms, passes) = gpu_time(&ctx, &cloud, &view, &config, options.frames)?;
            rows.push(Row {
                model: name.clone(),
                points: cloud.len(),
                what: format!(
                    "reconstruction: coverage IoU {iou:.4}, median relative depth error {depth:.5}"
                ),
                sqrt_k: from_view,
                gpu_ms: Some(gpu_ms),
                passes,
                ..Default::default()
            });
        }
    }
    // Time against points: the sampled mesh at each count.
    let mesh = crate::scene::load(&options.sampled)?;
    for &n in &options.counts {
        let mut cloud = crate::scene::sample::sample_mesh(&mesh, n, 1)?;
        cloud.faces = None;
        crate::scene::preprocess::preprocess(&mut cloud, &Default::default());
        let eye = eye_of(&cloud);
        let view = HprView::new(&cloud, eye, None, options.size);
        let radius = Radius::Density {
            spacing: spacing(&cloud),
        };
        let r = crate::hpr::flip_radius(&cloud.positions, eye, radius)?;
        let start = Instant::now();
        let ex = exact(&cloud.positions, eye, radius)?;
        let exact_s = start.elapsed().as_secs_f64();
        let points: Vec<DVec3> = cloud.positions.iter().map(|p| p.as_dvec3()).collect();
        let sphere = approx::bounding_sphere(&points).context("no points")?;
        let sqrt_k = approx::sqrt_k_for_view(sphere, eye.as_dvec3(), view.pixel_angle(), 4096);
        rows.push(Row {
            model: "sampled".into(),
            points: n,
            what: "exact".into(),
            visible: ex.visible.len(),
            exact: (1.0, 1.0, 1.0),
            cpu_s: Some(exact_s),
            ..Default::default()
        });
        // The GPU timing of the largest clouds: one frame after the warm-up.
        let frames = if n > 2_000_000 { 1 } else { options.frames };
        let (scene, _) = upload(&ctx, &cloud, &HPR_UPLOAD)?;
        let order = crate::point_streams::morton_order(&cloud.positions);
        // The complete set, at its default grid on the CPU and the GPU; where the cloud is the
        // one closest to a million points, on the CPU also against the grid (sectors per
        // point).
        let near_million = options
            .counts
            .iter()
            .min_by_key(|&&c| c.abs_diff(1_000_000))
            .is_some_and(|&c| c == n);
        let per_point: &[f64] = if near_million {
            &[1.0, 2.0, 4.0, 8.0, 16.0]
        } else {
            &[crate::hpr::COMPLETE_SECTORS_PER_POINT]
        };
        for &spp in per_point {
            let side = crate::hpr::complete_grid(crate::hpr::prefilter::finest_side(
                n,
                spp,
                crate::hpr::prefilter::LEVELS,
            ));
            let start = Instant::now();
            let cpu = crate::hpr::complete(&cloud.positions, eye, radius, Some(side))?;
            let cpu_s = start.elapsed().as_secs_f64();
            rows.push(Row {
                model: "sampled".into(),
                points: n,
                what: format!("complete, {spp} sectors per point (CPU)"),
                sqrt_k: side,
                visible: cpu.visible.len(),
                exact: agreement(&cpu.visible, &ex.visible),
                cpu_s: Some(cpu_s),
                ..Default::default()
            });
        }
        let side = crate::hpr::complete_side(n);
        let visible = complete_on_gpu(&ctx, &scene, &view, options.size, (r, side), &order)?;
        let config = format!("hpr:radius={},complete=1", factor_of(&cloud, r));
        let (gpu_ms, passes) = gpu_time(&ctx, &cloud, &view, &config, frames)?;
        rows.push(Row {
            model: "sampled".into(),
            points: n,
            what: "complete (GPU)".into(),
            sqrt_k: side,
            visible: visible.len(),
            exact: agreement(&visible, &ex.visible),
            gpu_ms: Some(gpu_ms),
            passes,
            ..Default::default()
        });
        drop(scene);
        for (propagation, sort) in [
            (ADAPTIVE, false),
            (Propagation::Fixed(3), false),
            (Propagation::Fixed(3), true),
        ] {
            // The CPU reference runs once per propagation (the sort changes only the GPU).
            let start = Instant::now();
            let cpu = approximate(&points, eye, sqrt_k, r, propagation)?;
            let cpu_s = (!sort).then(|| start.elapsed().as_secs_f64());
            let config = method(sqrt_k, factor_of(&cloud, r), propagation, sort);
            let (gpu_ms, passes) = gpu_time(&ctx, &cloud, &view, &config, frames)?;
            let sorted = if sort { ", radix sort" } else { ", atomicMax" };
            rows.push(Row {
                model: "sampled".into(),
                points: n,
                what: format!("{}{sorted}", label(propagation)),
                sqrt_k,
                visible: cpu.visible.len(),
                rounds: cpu.rounds,
                exact: agreement(&cpu.visible, &ex.visible),
                cpu_s,
                gpu_ms: Some(gpu_ms),
                passes,
                ..Default::default()
            });
        }
    }
    // The Asian Dragon's place in Table 5.3: the dragon mesh sampled to its point count.
    let mut cloud = crate::scene::sample::sample_mesh(&mesh, ASIAN_DRAGON_POINTS, 1)?;
    cloud.faces = None;
    crate::scene::preprocess::preprocess(&mut cloud, &Default::default());
    let view = HprView::new(&cloud, eye_of(&cloud), None, options.size);
    let radius = Radius::Density {
        spacing: spacing(&cloud),
    };
    let r = crate::hpr::flip_radius(&cloud.positions, eye_of(&cloud), radius)?;
    let (_, _, sqrt_k, m, _) = THESIS_TABLE_5_3[3];
    let mut row = reconstruction_row(
        &ctx,
        (&cloud, &mesh),
        &view,
        factor_of(&cloud, r),
        (sqrt_k, m),
        1,
    )?;
    row.model = "Asian Dragon (sampled dragon)".into();
    rows.push(row);
    if ctx.validation && ctx.validation_errors() > 0 {
        anyhow::bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    Ok(rows)
}

/// Exact HPR and the adaptive approximation at √k `sqrt_k` of `positions` from `eye`, as two
/// rows named by `what` (`{}` replaced by "exact" and "adaptive"), scored against exact HPR
/// and against `seen` when given (the model and point count are left for the caller).
fn sweep_rows(
    positions: &[Vec3],
    eye: Vec3,
    radius: Radius,
    sqrt_k: u32,
    seen: Option<&[u32]>,
    what: &str,
) -> Result<Vec<Row>> {
    let r = crate::hpr::flip_radius(positions, eye, radius)?;
    let ex = exact(positions, eye, radius)?;
    let points: Vec<DVec3> = positions.iter().map(|p| p.as_dvec3()).collect();
    let ap = approximate(&points, eye, sqrt_k, r, ADAPTIVE)?;
    Ok([("exact", &ex.visible), ("adaptive", &ap.visible)]
        .into_iter()
        .map(|(kind, visible)| Row {
            what: what.replace("{}", kind),
            sqrt_k,
            visible: visible.len(),
            exact: agreement(visible, &ex.visible),
            truth: seen.map(|s| agreement(visible, s)),
            ..Default::default()
        })
        .collect())
}

/// `cloud` with every position moved by Gaussian noise of standard deviation `sigma` per axis
/// (a fixed-seed generator: the same cloud every run).
fn with_noise(cloud: &Cloud, sigma: f32, seed: u64) -> Cloud {
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 / (1u64 << 53) as f64).max(f64::MIN_POSITIVE)
    };
    let mut gauss = move || {
        let (u, v) = (uniform(), uniform());
        ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
    };
    let mut out = cloud.clone();
    for p in &mut out.positions {
        *p += Vec3::new(gauss(), gauss(), gauss()) * sigma;
    }
    out
}

/// Intersection over union of the covered pixels of two frames, and the median relative depth
/// difference where both are covered.
fn coverage_agreement(a: &crate::frame::Frame, b: &crate::frame::Frame) -> (f64, f64) {
    let (mut both, mut either) = (0usize, 0usize);
    let mut errors = Vec::new();
    for i in 0..a.pixels() {
        let (ca, cb) = (a.covered(i), b.covered(i));
        if ca || cb {
            either += 1;
        }
        if ca && cb {
            both += 1;
            errors.push(((a.depth[i] - b.depth[i]).abs() / b.depth[i]) as f64);
        }
    }
    errors.sort_by(f64::total_cmp);
    let median = errors.get(errors.len() / 2).copied().unwrap_or(0.0);
    (both as f64 / either.max(1) as f64, median)
}

fn triple(t: (f64, f64, f64)) -> String {
    format!("{:.3} | {:.3} | {:.3}", t.0, t.1, t.2)
}

/// Writes `report.md`, `results.json` and the charts of `rows` into `dir`.
pub fn write_report(rows: &[Row], device: &str, (w, h): (u32, u32), dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(
        dir.join("results.json"),
        serde_json::to_string_pretty(rows)?,
    )?;
    let mut md = String::new();
    writeln!(md, "# HPR: exact, CPU and GPU approximation\n")?;
    writeln!(
        md,
        "Generated by `surfel hpr-study` on {device}. The eye is three bounding-sphere radii from \
         the centre along (0.5, 0.3, 0.81), looking at the centre; R is chosen from the sampling \
         density (`hpr::Radius::Density`, κ = {}) unless a row says otherwise. Precision, recall \
         and F1 are against exact HPR at the same R (\"vs exact\") and against the vertices the \
         mesh's depth buffer shows in the {w} × {h} view (\"vs truth\"). CPU times are single \
         runs of one thread; GPU times are medians of the HPR passes' timestamps in the frame \
         loop (adaptive propagation: up to 64 rounds are recorded, and the rounds after the \
         last change still cost an empty indirect dispatch each).\n",
        crate::hpr::DENSITY_KAPPA
    )?;
    let models: Vec<String> = {
        let mut m: Vec<String> = rows.iter().map(|r| r.model.clone()).collect();
        m.dedup();
        m
    };
    for model in models
        .iter()
        .filter(|m| *m != "sampled" && !m.starts_with("Asian"))
    {
        let of: Vec<&Row> = rows.iter().filter(|r| &r.model == model).collect();
        writeln!(md, "## {model} ({} points)\n", of[0].points)?;
        writeln!(md, "| configuration | √k | visible | rounds | P vs exact | R vs exact | F1 vs exact | P vs truth | R vs truth | F1 vs truth | CPU s | GPU ms |")?;
        writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
        for r in &of {
            if r.what.starts_with("reconstruction")
                || r.what.starts_with("table 5.")
                || r.what == "occupancy"
            {
                continue;
            }
            let truth = r.truth.map_or("– | – | –".into(), triple);
            writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                r.what,
                if r.sqrt_k > 0 {
                    r.sqrt_k.to_string()
                } else {
                    "–".into()
                },
                r.visible,
                r.rounds,
                triple(r.exact),
                truth,
                r.cpu_s.map_or("–".into(), |s| format!("{s:.3}")),
                r.gpu_ms.map_or("–".into(), |s| format!("{s:.2}")),
            )?;
        }
        for r in of.iter().filter(|r| r.what.starts_with("reconstruction")) {
            writeln!(
                md,
                "\nPartial reconstruction (`hpr-mesh`, √k = {}, {w} × {h}): {}; HPR passes \
                 {:.2} ms GPU.",
                r.sqrt_k,
                &r.what["reconstruction: ".len()..],
                r.gpu_ms.unwrap_or(0.0)
            )?;
            let passes: Vec<String> = r
                .passes
                .iter()
                .filter(|p| !p.0.starts_with("hpr.round.") && !p.0.starts_with("hpr.advance."))
                .map(|p| format!("{} {:.2}", p.0, p.1))
                .collect();
            writeln!(md, "Per pass (ms): {}.", passes.join(", "))?;
        }
        writeln!(md)?;
        // Fig. 5.1: visible points against k, one line per propagation.
        let mut series = Vec::new();
        for what in ["adaptive", "fixed 3x3", "fixed 5x5"] {
            let pts: Vec<(f64, f64)> = of
                .iter()
                .filter(|r| r.what.trim_end_matches(" (view)") == what)
                .map(|r| (f64::from(r.sqrt_k * r.sqrt_k), r.visible as f64))
                .collect();
            series.push((what.to_string(), pts));
        }
        let xs: Vec<f64> = series[0].1.iter().map(|p| p.0).collect();
        for level in ["exact", "complete (CPU)"] {
            if let Some(e) = of.iter().find(|r| r.what == level) {
                series.push((
                    level.into(),
                    xs.iter().map(|&x| (x, e.visible as f64)).collect(),
                ));
            }
        }
        let slug = model.to_lowercase().replace(' ', "-");
        crate::eval::charts::write_line_chart(
            dir,
            &format!("visible-vs-k-{slug}"),
            &format!("{model}: visible points against k (003 Fig. 5.1)"),
            ("sectors k", "visible points"),
            true,
            series,
        )?;
        writeln!(md, "![visible vs k](visible-vs-k-{slug}.svg)\n")?;
    }
    thesis_tables(&mut md, rows, &models, dir)?;
    let sampled: Vec<&Row> = rows.iter().filter(|r| r.model == "sampled").collect();
    if !sampled.is_empty() {
        writeln!(md, "## Time against points (the sampled dragon mesh)\n")?;
        writeln!(
            md,
            "The complete set's rows at the cloud nearest a million points sweep its finest \
             grid (sectors per point; the default is {}).\n",
            crate::hpr::COMPLETE_SECTORS_PER_POINT
        )?;
        writeln!(md, "| points | configuration | √k | visible | P vs exact | R vs exact | F1 vs exact | CPU s | GPU ms (HPR passes) | GPU per pass (ms) |")?;
        writeln!(md, "|---|---|---|---|---|---|---|---|---|---|")?;
        for r in &sampled {
            let passes: Vec<String> = r
                .passes
                .iter()
                .filter(|p| !p.0.starts_with("hpr.round.") && !p.0.starts_with("hpr.advance."))
                .map(|p| format!("{} {:.2}", p.0.trim_start_matches("hpr."), p.1))
                .collect();
            let rounds: f64 = r
                .passes
                .iter()
                .filter(|p| p.0.starts_with("hpr.round.") || p.0.starts_with("hpr.advance."))
                .map(|p| p.1)
                .sum();
            let rounds = if rounds > 0.0 {
                format!(", rounds {rounds:.2}")
            } else {
                String::new()
            };
            writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {}{rounds} |",
                r.points,
                r.what,
                if r.sqrt_k > 0 {
                    r.sqrt_k.to_string()
                } else {
                    "–".into()
                },
                r.visible,
                triple(r.exact),
                r.cpu_s.map_or("–".into(), |s| format!("{s:.3}")),
                r.gpu_ms.map_or("–".into(), |s| format!("{s:.2}")),
                passes.join(", "),
            )?;
        }
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for r in &sampled {
            let mut add = |name: String, ms: f64| match series.iter_mut().find(|s| s.0 == name) {
                Some(s) => s.1.push((r.points as f64, ms)),
                None => series.push((name, vec![(r.points as f64, ms)])),
            };
            if let Some(s) = r.cpu_s {
                add(
                    format!("CPU {}", r.what.split(',').next().unwrap_or("")),
                    s * 1000.0,
                );
            }
            if let Some(ms) = r.gpu_ms {
                add(format!("GPU {}", r.what), ms);
            }
        }
        crate::eval::charts::write_line_chart(
            dir,
            "time-vs-points",
            "HPR time against points",
            ("points", "milliseconds"),
            true,
            series,
        )?;
        writeln!(md, "\n![time vs points](time-vs-points.svg)\n")?;
    }
    std::fs::write(dir.join("report.md"), md)?;
    Ok(())
}

/// The sections of 003 Table 5.2, Fig. 5.9 and Table 5.3 from `rows`.
fn thesis_tables(md: &mut String, rows: &[Row], models: &[String], dir: &Path) -> Result<()> {
    let of = |model: &str, what: &str| {
        rows.iter()
            .find(move |r| r.model == model && r.what == what)
    };
    writeln!(
        md,
        "## 003 Table 5.2: the √k at which the approximation reaches the exact count\n"
    )?;
    writeln!(
        md,
        "For each propagation the smallest √k of 64 · 2^(i/4) (up to 4096) at which the CPU \
         approximation finds at least {:.0} % as many points as exact HPR, the agreement of those points \
         with exact HPR's, and the times: exact HPR and the approximation on the CPU (single \
         runs), the approximation's HPR passes on the GPU (median). The thesis' m = 10 is the \
         centred 11 × 11 window. The complete set (beyond 003, its default grid) is listed for \
         comparison. The thesis' columns are its models (ours stand in: the bunny for Bimba, \
         the 50 K armadillo and Buddha for the 173 K and 720 K scans) on a GTX 470, in frames \
         per second of the whole frame.\n",
        100.0 * REACHED
    )?;
    writeln!(md, "| model | points | exact visible | exact s | configuration | √k | visible | P | R | F1 | CPU s | GPU ms | thesis model, points, visible | thesis fps exact / CPU / GPU (m) |")?;
    writeln!(
        md,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    for model in models {
        let Some(thesis) =
            thesis_model(model).and_then(|m| THESIS_TABLE_5_2.iter().find(|t| t.0 == m))
        else {
            continue;
        };
        let Some(exact) = of(model, "exact") else {
            continue;
        };
        let mut first = true;
        let searched = rows
            .iter()
            .filter(|r| &r.model == model && r.what.starts_with("table 5.2: "));
        let complete = rows
            .iter()
            .filter(|r| &r.model == model && r.what == "complete (GPU)");
        for r in searched.chain(complete) {
            let (name, points, visible, e, c, g, m) = *thesis;
            let (lead, theirs) = if first {
                (
                    format!(
                        "{model} | {} | {} | {:.3}",
                        exact.points,
                        exact.visible,
                        exact.cpu_s.unwrap_or(0.0)
                    ),
                    format!("{name}, {points}, ~{visible} | {e} / {c} / {g} (m = {m})"),
                )
            } else {
                (" | | | ".into(), " | ".into())
            };
            first = false;
            let reached = r.sqrt_k > 0 || r.what == "complete (GPU)";
            writeln!(
                md,
                "| {lead} | {} | {} | {} | {} | {} | {} | {theirs} |",
                r.what.trim_start_matches("table 5.2: "),
                if reached {
                    r.sqrt_k.to_string()
                } else {
                    "not by 4096".into()
                },
                if reached {
                    r.visible.to_string()
                } else {
                    format!(
                        "{} ({:.1} % at 4096)",
                        r.visible,
                        100.0 * r.visible as f64 / exact.visible.max(1) as f64
                    )
                },
                if reached {
                    triple(r.exact)
                } else {
                    "– | – | –".into()
                },
                r.cpu_s.map_or("–".into(), |s| format!("{s:.3}")),
                r.gpu_ms.map_or("–".into(), |s| format!("{s:.2}")),
            )?;
        }
    }
    // Fig. 5.9: occupancy against k.
    let mut series = Vec::new();
    for model in models {
        let occupancy: Vec<&Row> = rows
            .iter()
            .filter(|r| &r.model == model && r.what == "occupancy")
            .collect();
        if occupancy.is_empty() {
            continue;
        }
        for (what, pick) in [
            ("sectors holding a point", 0),
            ("distinct extremes (adaptive)", 1),
        ] {
            let pts = occupancy
                .iter()
                .filter_map(|r| {
                    let o = r.occupancy?;
                    let y = if pick == 0 { o.0 } else { o.1 };
                    Some((f64::from(r.sqrt_k).powi(2), 100.0 * y))
                })
                .collect();
            series.push((format!("{model}: {what}"), pts));
        }
    }
    if !series.is_empty() {
        crate::eval::charts::write_line_chart(
            dir,
            "occupancy-vs-k",
            "Sector occupancy against k (003 Fig. 5.9)",
            ("sectors k", "% of sectors"),
            true,
            series,
        )?;
        writeln!(md, "\n## 003 Fig. 5.9: sector occupancy against k\n")?;
        writeln!(
            md,
            "The share of the k sectors that hold a point, and that hold a distinct extreme after \
             adaptive propagation (the visible count over k): past the k at which the \
             approximation reaches the exact count most sectors are empty or repeat a \
             neighbour's extreme, which is the memory the thesis names as the method's limit.\n"
        )?;
        writeln!(md, "![occupancy vs k](occupancy-vs-k.svg)\n")?;
    }
    let recon: Vec<&Row> = rows
        .iter()
        .filter(|r| r.what.starts_with("table 5.3: "))
        .collect();
    if !recon.is_empty() {
        writeln!(
            md,
            "## 003 Table 5.3: the partial reconstruction at the thesis' √k and m\n"
        )?;
        writeln!(
            md,
            "`hpr-mesh` with fixed propagation, against the mesh's own rendering (coverage IoU of \
             the covered pixels, median relative depth error where both cover); GPU time of the \
             HPR and triangulation passes (median). The Asian Dragon (3.6 M points) is the \
             dragon mesh sampled to its point count. Our stand-ins hold fewer points than the \
             thesis' models at the same √k: more sectors per point, which fixed propagation \
             leaves empty (holes, a lower coverage).\n"
        )?;
        writeln!(md, "| model | points | √k | m | coverage IoU | median depth error | GPU ms | thesis model, points | thesis fps |")?;
        writeln!(md, "|---|---|---|---|---|---|---|---|---|")?;
        for r in recon {
            let thesis = thesis_model(&r.model)
                .or(r.model.starts_with("Asian").then_some("Asian Dragon"))
                .and_then(|m| THESIS_TABLE_5_3.iter().find(|t| t.0 == m));
            let rest = r.what.trim_start_matches("table 5.3: ");
            let (m, rest) = rest.split_once(", ").unwrap_or((rest, ""));
            let iou = rest
                .split(", ")
                .map(|p| p.rsplit(' ').next().unwrap_or(""))
                .collect::<Vec<_>>();
            writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} |",
                r.model,
                r.points,
                r.sqrt_k,
                m.trim_start_matches("m = "),
                iou.join(" | "),
                r.gpu_ms.map_or("–".into(), |s| format!("{s:.2}")),
                thesis.map_or(" | ".into(), |t| format!("{}, {} | {}", t.0, t.1, t.4)),
            )?;
        }
        writeln!(md)?;
    }
    Ok(())
}

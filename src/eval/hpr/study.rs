//! The HPR study's measurements: per model, exact HPR, the approximation over a range of k on
//! the CPU and the GPU, the complete set, 003 Table 5.2 and Fig. 5.9, the R and noise sweeps
//! and the partial reconstruction (003 Table 5.3); time against points on a sampled mesh.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use glam::{DVec3, Vec3};
use serde::Serialize;

use super::render::{gpu_time, mesh_visibility, render_once, PassTimes};
use crate::gpu::{Context, ContextOptions};
use crate::gpu_scene::{upload, GpuScene, UploadOptions};
use crate::hpr::approx::{self, Params, Propagation};
use crate::hpr::view::HprView;
use crate::hpr::{agreement, exact, spacing, Radius};
use crate::methods::hpr::{evaluate, Settings};
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

/// The largest √k of the view's sector grid.
const MAX_SQRT_K: u32 = 4096;

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

/// 003 Table 5.3: the partial reconstruction at 900 × 900: model, points, √k, m, frames per
/// second.
pub(super) const THESIS_TABLE_5_3: [(&str, u32, u32, u32, f64); 4] = [
    ("Bimba", 74_764, 923, 3, 50.0),
    ("Armadillo", 172_974, 1269, 3, 25.0),
    ("Buddha", 719_560, 678, 3, 25.0),
    ("Asian Dragon", 3_609_455, 906, 1, 11.0),
];

/// The thesis model a study model stands in for (by name: bunny for Bimba, the others by
/// their own names; the sampled dragon mesh for the Asian Dragon).
pub(super) fn thesis_model(name: &str) -> Option<&'static str> {
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
pub(super) const REACHED: f64 = 0.99;

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

/// A cloud the study runs HPR on, seen from [`eye_of`] in the study's view.
struct Subject<'a> {
    cloud: &'a Cloud,
    eye: Vec3,
    view: HprView,
    /// R from the sampling density.
    radius: Radius,
    /// R in scene units.
    r: f64,
    /// R as the methods' `radius` factor ([`factor_of`]).
    factor: f64,
    /// The positions in f64.
    points: Vec<DVec3>,
    /// √k of one sector per pixel of the bounding sphere's projection.
    from_view: u32,
}

impl<'a> Subject<'a> {
    fn new(cloud: &'a Cloud, size: (u32, u32)) -> Result<Self> {
        let eye = eye_of(cloud);
        let view = HprView::new(cloud, eye, None, size);
        let radius = Radius::Density {
            spacing: spacing(cloud),
        };
        let r = crate::hpr::flip_radius(&cloud.positions, eye, radius)?;
        let points: Vec<DVec3> = cloud.positions.iter().map(|p| p.as_dvec3()).collect();
        let sphere = approx::bounding_sphere(&points).context("no points")?;
        let from_view =
            approx::sqrt_k_for_view(sphere, eye.as_dvec3(), view.pixel_angle(), MAX_SQRT_K);
        Ok(Self {
            cloud,
            eye,
            view,
            radius,
            r,
            factor: factor_of(cloud, r),
            points,
            from_view,
        })
    }

    /// The CPU reference at √k `sqrt_k` with `propagation`.
    fn approximate(&self, sqrt_k: u32, propagation: Propagation) -> Result<approx::Approx> {
        approximate(&self.points, self.eye, sqrt_k, self.r, propagation)
    }

    /// Median GPU milliseconds of the HPR passes of `config` rendering the cloud (and each).
    fn gpu_time(&self, ctx: &Arc<Context>, config: &str, frames: u32) -> Result<(f64, PassTimes)> {
        gpu_time(ctx, self.cloud, &self.view, config, frames)
    }

    /// Exact HPR and its CPU seconds.
    fn exact(&self) -> Result<(crate::hpr::Visibility, f64)> {
        let start = Instant::now();
        let visibility = exact(&self.cloud.positions, self.eye, self.radius)?;
        Ok((visibility, start.elapsed().as_secs_f64()))
    }
}

/// A cloud uploaded for the GPU passes and the file index of each stream index.
struct Uploaded {
    scene: GpuScene,
    order: Vec<u32>,
}

impl Uploaded {
    fn new(ctx: &Arc<Context>, cloud: &Cloud) -> Result<Self> {
        let (scene, _) = upload(ctx, cloud, &HPR_UPLOAD)?;
        // Stream order is the Morton order of the positions.
        let order = crate::point_streams::morton_order(&cloud.positions);
        Ok(Self { scene, order })
    }

    /// The points the GPU passes with `settings` find visible in `view`, as indices of the
    /// file's order, ascending, and the propagation rounds they ran.
    fn visible(
        &self,
        ctx: &Arc<Context>,
        view: &HprView,
        settings: &Settings,
    ) -> Result<(Vec<u32>, u32)> {
        let gpu = evaluate(
            ctx,
            &self.scene,
            (view.camera.view(), view.proj()),
            (view.width, view.height),
            settings,
            false,
        )?;
        let mut visible: Vec<u32> = gpu
            .visible
            .iter()
            .map(|&i| self.order[i as usize])
            .collect();
        visible.sort_unstable();
        Ok((visible, gpu.state.rounds))
    }
}

/// Precision, recall and F1.
type Scores = (f64, f64, f64);

/// What a visible set is scored against: exact HPR's visible points and, for a mesh, the
/// vertices its depth buffer shows.
struct References<'a> {
    exact: &'a [u32],
    seen: Option<&'a [u32]>,
}

impl References<'_> {
    /// Precision, recall and F1 of `visible` against exact HPR and against `seen`.
    fn score(&self, visible: &[u32]) -> (Scores, Option<Scores>) {
        (
            agreement(visible, self.exact),
            self.seen.map(|s| agreement(visible, s)),
        )
    }
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

/// Runs the study; returns the rows and writes nothing.
pub fn run(options: &StudyOptions) -> Result<Vec<Row>> {
    let ctx = Arc::new(Context::new(&ContextOptions::from_env())?);
    let mut rows = Vec::new();
    for (name, path) in &options.models {
        rows.extend(model_rows(&ctx, name, path, options)?);
    }
    // Time against points: the sampled mesh at each count.
    let mesh = crate::scene::load(&options.sampled)?;
    for &n in &options.counts {
        rows.extend(sampled_rows(&ctx, &mesh, n, options)?);
    }
    rows.push(asian_dragon_row(&ctx, &mesh, options.size)?);
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    Ok(rows)
}

/// The rows of the model `name` at `path`: exact HPR, the approximation over a range of √k,
/// the complete set, 003 Table 5.2 and Fig. 5.9 where the model stands in for a thesis model,
/// the sweeps, and for a mesh the partial reconstructions.
fn model_rows(
    ctx: &Arc<Context>,
    name: &str,
    path: &Path,
    options: &StudyOptions,
) -> Result<Vec<Row>> {
    let cloud = crate::scene::input::load_prepared(path, &Default::default())
        .with_context(|| path.display().to_string())?;
    let s = Subject::new(&cloud, options.size)?;
    let (truth_exact, exact_s) = s.exact()?;
    let seen = if cloud.faces.is_some() {
        Some(mesh_visibility(&cloud, &s.view)?)
    } else {
        None
    };
    let references = References {
        exact: &truth_exact.visible,
        seen: seen.as_deref(),
    };
    let (e, t) = references.score(&truth_exact.visible);
    let mut rows = vec![Row {
        what: "exact".into(),
        visible: truth_exact.visible.len(),
        exact: e,
        truth: t,
        cpu_s: Some(exact_s),
        ..Default::default()
    }];
    let uploaded = Uploaded::new(ctx, &cloud)?;
    rows.extend(grid_rows(ctx, &s, &uploaded, &references, options.frames)?);
    rows.push(complete_cpu_row(&s, &references)?);
    rows.push(complete_gpu_row(
        ctx,
        &s,
        &uploaded,
        &references,
        options.frames,
    )?);
    if thesis_model(name).is_some() {
        rows.extend(thesis_rows(ctx, &s, &truth_exact.visible, options.frames)?);
    }
    rows.extend(sweeps(&s, seen.as_deref())?);
    if cloud.faces.is_some() {
        rows.extend(reconstruction_rows(ctx, &s, name, options.frames)?);
    }
    for row in &mut rows {
        row.model = name.to_string();
        row.points = cloud.len();
    }
    Ok(rows)
}

/// The approximation at √k 64 to 2048 and the view's, with adaptive propagation and fixed 3 × 3
/// and 5 × 5: the GPU passes' visible points scored, the CPU reference and the GPU passes
/// timed.
fn grid_rows(
    ctx: &Arc<Context>,
    s: &Subject,
    uploaded: &Uploaded,
    references: &References,
    frames: u32,
) -> Result<Vec<Row>> {
    let mut ks = vec![64, 128, 256, 512, 1024, 2048, s.from_view];
    ks.sort_unstable();
    ks.dedup();
    let mut rows = Vec::new();
    for &sqrt_k in &ks {
        for propagation in [ADAPTIVE, Propagation::Fixed(3), Propagation::Fixed(5)] {
            let start = Instant::now();
            s.approximate(sqrt_k, propagation)?;
            let cpu_s = start.elapsed().as_secs_f64();
            let settings = Settings::grid(sqrt_k, s.r, propagation, false);
            let (visible, rounds) = uploaded.visible(ctx, &s.view, &settings)?;
            let (e, t) = references.score(&visible);
            let config = method(sqrt_k, s.factor, propagation, false);
            let (gpu_ms, passes) = s.gpu_time(ctx, &config, frames)?;
            let note = if sqrt_k == s.from_view { " (view)" } else { "" };
            rows.push(Row {
                what: format!("{}{note}", label(propagation)),
                sqrt_k,
                visible: visible.len(),
                rounds,
                exact: e,
                truth: t,
                cpu_s: Some(cpu_s),
                gpu_ms: Some(gpu_ms),
                passes,
                ..Default::default()
            });
        }
    }
    Ok(rows)
}

/// The complete visible set (beyond 003) on the CPU at its default grid, scored and timed.
fn complete_cpu_row(s: &Subject, references: &References) -> Result<Row> {
    let side = crate::hpr::complete_side(s.cloud.len());
    let start = Instant::now();
    let cpu = crate::hpr::complete(&s.cloud.positions, s.eye, s.radius, Some(side))?;
    let cpu_s = start.elapsed().as_secs_f64();
    let (e, t) = references.score(&cpu.visible);
    Ok(Row {
        what: "complete (CPU)".into(),
        sqrt_k: side,
        visible: cpu.visible.len(),
        exact: e,
        truth: t,
        cpu_s: Some(cpu_s),
        ..Default::default()
    })
}

/// The complete visible set on the GPU at its default grid, scored, its passes timed over
/// `frames` frames.
fn complete_gpu_row(
    ctx: &Arc<Context>,
    s: &Subject,
    uploaded: &Uploaded,
    references: &References,
    frames: u32,
) -> Result<Row> {
    let side = crate::hpr::complete_side(s.cloud.len());
    let mut settings = Settings::grid(1, s.r, Propagation::Fixed(3), false);
    settings.params.complete_side = side;
    settings.extremes = false;
    let (visible, _) = uploaded.visible(ctx, &s.view, &settings)?;
    let (e, t) = references.score(&visible);
    let config = format!("hpr:radius={},complete=1", s.factor);
    let (gpu_ms, passes) = s.gpu_time(ctx, &config, frames)?;
    Ok(Row {
        what: "complete (GPU)".into(),
        sqrt_k: side,
        visible: visible.len(),
        exact: e,
        truth: t,
        gpu_ms: Some(gpu_ms),
        passes,
        ..Default::default()
    })
}

/// 003 Table 5.2 and Fig. 5.9 for one model: for adaptive propagation and fixed m = 3 and
/// m = 10 (an 11 × 11 gather: the window is centred, reach m / 2), the smallest √k of
/// [`search_sqrt_ks`] at which the CPU approximation finds [`REACHED`] of the points exact HPR
/// finds (`exact_visible`), scored against them and timed on the CPU and the GPU (√k 0: not
/// reached by the largest); and at every √k the sector occupancy (sectors holding a point;
/// distinct extremes after adaptive propagation).
fn thesis_rows(
    ctx: &Arc<Context>,
    s: &Subject,
    exact_visible: &[u32],
    frames: u32,
) -> Result<Vec<Row>> {
    let propagations = [ADAPTIVE, Propagation::Fixed(3), Propagation::Fixed(10)];
    let mut reached = [false; 3];
    let mut largest = [0usize; 3];
    let mut rows = Vec::new();
    for sqrt_k in search_sqrt_ks() {
        let k = f64::from(sqrt_k).powi(2);
        let own = s.approximate(sqrt_k, Propagation::Fixed(1))?;
        let occupied = own.max.iter().filter(|&&m| m != u32::MAX).count() as f64 / k;
        for (i, &propagation) in propagations.iter().enumerate() {
            let adaptive = matches!(propagation, Propagation::Adaptive { .. });
            if reached[i] && !adaptive {
                continue;
            }
            let start = Instant::now();
            let ap = s.approximate(sqrt_k, propagation)?;
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
                let config = method(sqrt_k, s.factor, propagation, false);
                let (gpu_ms, passes) = s.gpu_time(ctx, &config, frames)?;
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

/// The R sweep (factors of the diameter) with exact HPR and the view's approximation and, with
/// a mesh's visibility `seen`, the noise sweep: Gaussian offsets (σ in sample spacings) against
/// the clean mesh's visibility, R from the density of the clean cloud.
fn sweeps(s: &Subject, seen: Option<&[u32]>) -> Result<Vec<Row>> {
    let sweep = |positions: &[Vec3], radius: Radius, what: &str| -> Result<Vec<Row>> {
        sweep_rows(positions, s.eye, radius, s.from_view, seen, what)
    };
    let mut rows = Vec::new();
    for f in [100.0, 1_000.0, 10_000.0, 30_000.0] {
        let what = format!("R sweep: {{}}, R = {f} x diameter");
        rows.extend(sweep(&s.cloud.positions, Radius::Factor(f), &what)?);
    }
    if seen.is_some() {
        for sigma in [0.25, 0.5, 1.0, 2.0] {
            let noisy = with_noise(s.cloud, sigma * spacing(s.cloud) as f32, 7);
            let what = format!("noise: {{}}, sigma = {sigma} spacing");
            rows.extend(sweep(&noisy.positions, s.radius, &what)?);
        }
    }
    Ok(rows)
}

/// Exact HPR and the adaptive approximation at √k `sqrt_k` of `positions` from `eye`, as two
/// rows named by `what` (`{}` replaced by "exact" and "adaptive"), scored against exact HPR
/// and against `seen` when given.
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

/// The partial reconstruction of the model `name`'s mesh against its own rendering: at the
/// thesis' √k and m where it stands in for a thesis model (003 Table 5.3), and at the view's √k.
fn reconstruction_rows(
    ctx: &Arc<Context>,
    s: &Subject,
    name: &str,
    frames: u32,
) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let thesis = thesis_model(name).and_then(|m| THESIS_TABLE_5_3.iter().find(|t| t.0 == m));
    if let Some(&(_, _, sqrt_k, m, _)) = thesis {
        rows.push(table_5_3_row(ctx, s, s.cloud, (sqrt_k, m), frames)?);
    }
    let config = format!(
        "hpr-mesh:sectors={0},max_sectors={0},radius={1}",
        s.from_view, s.factor
    );
    let (coverage, gpu_ms, passes) = reconstruction(ctx, s, s.cloud, &config, frames)?;
    rows.push(Row {
        what: format!("reconstruction: {coverage}"),
        sqrt_k: s.from_view,
        gpu_ms: Some(gpu_ms),
        passes,
        ..Default::default()
    });
    Ok(rows)
}

/// The partial reconstruction at √k and fixed m (`hpr-mesh`) of `s` against the rendered
/// `mesh`, a row of 003 Table 5.3 (the model and point count left for the caller).
fn table_5_3_row(
    ctx: &Arc<Context>,
    s: &Subject,
    mesh: &Cloud,
    (sqrt_k, m): (u32, u32),
    frames: u32,
) -> Result<Row> {
    let config = format!(
        "hpr-mesh:sectors={sqrt_k},max_sectors={sqrt_k},m={m},rounds=1,radius={}",
        s.factor
    );
    let (coverage, gpu_ms, passes) = reconstruction(ctx, s, mesh, &config, frames)?;
    Ok(Row {
        what: format!("table 5.3: m = {m}, {coverage}"),
        sqrt_k,
        gpu_ms: Some(gpu_ms),
        passes,
        ..Default::default()
    })
}

/// The reconstruction `config` (an `hpr-mesh` configuration) of `s` in its view against the
/// rendered `mesh`: the coverage IoU and median relative depth error as a row names them, and
/// the GPU time of its HPR passes (and each) over `frames` frames.
fn reconstruction(
    ctx: &Arc<Context>,
    s: &Subject,
    mesh: &Cloud,
    config: &str,
    frames: u32,
) -> Result<(String, f64, PassTimes)> {
    let recon = render_once(s.cloud, &s.view, config)?;
    let reference = render_once(mesh, &s.view, "mesh:samples=1")?;
    let (iou, depth) = coverage_agreement(&recon, &reference);
    let (gpu_ms, passes) = s.gpu_time(ctx, config, frames)?;
    let coverage = format!("coverage IoU {iou:.4}, median relative depth error {depth:.5}");
    Ok((coverage, gpu_ms, passes))
}

/// `n` points sampled from `mesh`, without faces, with normals and radii.
fn sampled(mesh: &Cloud, n: usize) -> Result<Cloud> {
    let mut cloud = crate::scene::sample::sample_mesh(mesh, n, 1)?;
    cloud.faces = None;
    crate::scene::preprocess::preprocess(&mut cloud, &Default::default());
    Ok(cloud)
}

/// The rows of `n` points sampled from `mesh`: exact HPR, the complete set on the CPU (at the
/// count nearest a million points, over a range of sectors per point) and the GPU, and the
/// view's approximation sort-free and sorted.
fn sampled_rows(
    ctx: &Arc<Context>,
    mesh: &Cloud,
    n: usize,
    options: &StudyOptions,
) -> Result<Vec<Row>> {
    let cloud = sampled(mesh, n)?;
    let s = Subject::new(&cloud, options.size)?;
    let (ex, exact_s) = s.exact()?;
    let mut rows = vec![Row {
        what: "exact".into(),
        visible: ex.visible.len(),
        exact: (1.0, 1.0, 1.0),
        cpu_s: Some(exact_s),
        ..Default::default()
    }];
    // The GPU timing of the largest clouds: one frame after the warm-up.
    let frames = if n > 2_000_000 { 1 } else { options.frames };
    let uploaded = Uploaded::new(ctx, &cloud)?;
    let near_million = options
        .counts
        .iter()
        .min_by_key(|&&c| c.abs_diff(1_000_000))
        .is_some_and(|&c| c == n);
    rows.extend(complete_per_point_rows(&s, &ex.visible, near_million)?);
    let references = References {
        exact: &ex.visible,
        seen: None,
    };
    rows.push(complete_gpu_row(ctx, &s, &uploaded, &references, frames)?);
    drop(uploaded);
    rows.extend(sorted_rows(ctx, &s, &ex.visible, frames)?);
    for row in &mut rows {
        row.model = "sampled".into();
        row.points = n;
    }
    Ok(rows)
}

/// The complete set on the CPU at its default sectors per point or, `sweep`, at 1 to 16,
/// scored against exact HPR's `exact_visible` and timed.
fn complete_per_point_rows(s: &Subject, exact_visible: &[u32], sweep: bool) -> Result<Vec<Row>> {
    let per_point: &[f64] = if sweep {
        &[1.0, 2.0, 4.0, 8.0, 16.0]
    } else {
        &[crate::hpr::COMPLETE_SECTORS_PER_POINT]
    };
    let mut rows = Vec::new();
    for &spp in per_point {
        let side = crate::hpr::complete_grid(crate::hpr::prefilter::finest_side(
            s.cloud.len(),
            spp,
            crate::hpr::prefilter::LEVELS,
        ));
        let start = Instant::now();
        let cpu = crate::hpr::complete(&s.cloud.positions, s.eye, s.radius, Some(side))?;
        let cpu_s = start.elapsed().as_secs_f64();
        rows.push(Row {
            what: format!("complete, {spp} sectors per point (CPU)"),
            sqrt_k: side,
            visible: cpu.visible.len(),
            exact: agreement(&cpu.visible, exact_visible),
            cpu_s: Some(cpu_s),
            ..Default::default()
        });
    }
    Ok(rows)
}

/// The view's approximation with adaptive propagation and fixed 3 × 3 by `atomicMax`, and
/// fixed 3 × 3 by the radix sort: the CPU reference scored against `exact_visible` and timed
/// (once per propagation: the sort changes only the GPU), the GPU passes timed.
fn sorted_rows(
    ctx: &Arc<Context>,
    s: &Subject,
    exact_visible: &[u32],
    frames: u32,
) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for (propagation, sort) in [
        (ADAPTIVE, false),
        (Propagation::Fixed(3), false),
        (Propagation::Fixed(3), true),
    ] {
        let start = Instant::now();
        let cpu = s.approximate(s.from_view, propagation)?;
        let cpu_s = (!sort).then(|| start.elapsed().as_secs_f64());
        let config = method(s.from_view, s.factor, propagation, sort);
        let (gpu_ms, passes) = s.gpu_time(ctx, &config, frames)?;
        let sorted = if sort { ", radix sort" } else { ", atomicMax" };
        rows.push(Row {
            what: format!("{}{sorted}", label(propagation)),
            sqrt_k: s.from_view,
            visible: cpu.visible.len(),
            rounds: cpu.rounds,
            exact: agreement(&cpu.visible, exact_visible),
            cpu_s,
            gpu_ms: Some(gpu_ms),
            passes,
            ..Default::default()
        });
    }
    Ok(rows)
}

/// The Asian Dragon's place in 003 Table 5.3: `mesh` sampled to its point count, its partial
/// reconstruction against `mesh`.
fn asian_dragon_row(ctx: &Arc<Context>, mesh: &Cloud, size: (u32, u32)) -> Result<Row> {
    let cloud = sampled(mesh, ASIAN_DRAGON_POINTS)?;
    let s = Subject::new(&cloud, size)?;
    let (_, _, sqrt_k, m, _) = THESIS_TABLE_5_3[3];
    let row = table_5_3_row(ctx, &s, mesh, (sqrt_k, m), 1)?;
    Ok(Row {
        model: "Asian Dragon (sampled dragon)".into(),
        points: cloud.len(),
        ..row
    })
}

/// The radius factor (of the bounding box's diagonal, as the methods' `radius` takes it) equal
/// to `r`.
fn factor_of(cloud: &Cloud, r: f64) -> f64 {
    r / crate::hpr::diagonal(&cloud.positions)
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

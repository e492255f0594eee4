//! The points of a cloud visible from a view by the algorithm a request names: exact HPR, an
//! approximate hull or the complete visible set on the CPU (`crate::hpr`), or the sector
//! approximation on the CPU (`crate::hpr::approx`) or the GPU ([`evaluate`]).

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};

use super::{evaluate, Settings};
use crate::gpu::{Context, ContextOptions};
use crate::gpu_scene::{upload, UploadOptions};
use crate::hpr::approx::{self, Params, Propagation};
use crate::hpr::view::HprView;
use crate::hpr::Radius;
use crate::scene::Cloud;

/// The approximate convex hulls of 003 ch. 3 (`surfel hpr --hull`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HullKind {
    /// Bentley, Faust and Preparata: extremes per grid cell, then their exact hull (§3.1).
    Bfp,
    /// Kavan, Kolingerová and Žára: extremes per sphere sector, refined in O(k²) (§3.2).
    Kavan,
    /// The exact hull of the sector extremes (§3.3).
    Hybrid,
}

/// What decides visibility.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Algorithm {
    /// Exact HPR (003 §2.1).
    Exact,
    /// The sector approximation (003 ch. 4).
    Sectors,
    /// The complete visible set (`hpr::complete`); on the GPU, the sector approximation's
    /// passes deciding by it.
    Complete,
    /// An approximate convex hull (003 ch. 3).
    Hull(HullKind),
}

/// Which points [`visible_points`] finds and how.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Request {
    pub(crate) algorithm: Algorithm,
    /// The flipping radius R.
    pub(crate) radius: Radius,
    /// Sectors k: of the sector approximation (rounded to a square √k × √k grid; `None`: one
    /// per pixel of the bounding sphere's projection), of a hull (`None`: 65,536), or of the
    /// complete set's finest grid (`None`: about four per point).
    pub(crate) sectors: Option<u64>,
    /// Fixed propagation over an m × m window; adaptive without it.
    pub(crate) m: Option<u32>,
    /// Adaptive propagation's round cap (`None`: until stable on the CPU, 256 on the GPU).
    pub(crate) rounds: Option<u32>,
    /// The sector approximation on the GPU.
    pub(crate) gpu: bool,
    /// On the GPU, the radix sort by sector and segmented maximum instead of `atomicMax`.
    pub(crate) sort: bool,
    /// The longest projected edge in pixels of the triangles kept (`None`: no limit).
    pub(crate) max_edge: Option<f32>,
}

impl Request {
    /// `algorithm` at flipping radius `radius`, every other choice its default, on the CPU and
    /// without an edge limit.
    pub(crate) fn new(algorithm: Algorithm, radius: Radius) -> Self {
        Self {
            algorithm,
            radius,
            sectors: None,
            m: None,
            rounds: None,
            gpu: false,
            sort: false,
            max_edge: None,
        }
    }
}

/// What [`visible_points`] found.
pub(crate) struct Found {
    pub(crate) visibility: crate::hpr::Visibility,
    /// How the points were found.
    pub(crate) note: String,
    /// The sector approximation's √k (the complete set: its sectors per angle).
    pub(crate) sectors: Option<u32>,
}

/// The reconstruction's longest projected edge in pixels unless `surfel hpr --max-edge` says.
pub(crate) const DEFAULT_MAX_EDGE: f32 = 10.0;

/// The largest √k the approximation allocates when k comes from the view.
const MAX_SQRT_K: u32 = 4096;

/// The cells or sectors of an approximate hull unless the request gives k.
const DEFAULT_HULL_K: u64 = 65_536;

/// The points of `cloud` visible from the view's eye.
pub(crate) fn visible_points(cloud: &Cloud, view: &HprView, request: &Request) -> Result<Found> {
    let eye = view.camera.eye;
    match request.algorithm {
        Algorithm::Exact => exact_visible_points(cloud, view, request),
        Algorithm::Hull(kind) => approximate_hull(
            cloud,
            eye,
            request.radius,
            kind,
            request.sectors.unwrap_or(DEFAULT_HULL_K),
        ),
        Algorithm::Complete if !request.gpu => complete_visible_points(cloud, eye, request),
        Algorithm::Sectors | Algorithm::Complete => sector_visible_points(cloud, view, request),
    }
}

/// The complete visible set on the CPU.
fn complete_visible_points(cloud: &Cloud, eye: glam::Vec3, request: &Request) -> Result<Found> {
    let side = complete_side(cloud, request.sectors);
    let visibility = crate::hpr::complete(&cloud.positions, eye, request.radius, Some(side))?;
    Ok(Found {
        note: format!(
            "method            complete visible set, {side} sectors per angle, {} grids",
            crate::hpr::prefilter::LEVELS
        ),
        visibility,
        sectors: Some(side),
    })
}

/// The complete set's finest grid: from k sectors, else its default for the cloud's size.
fn complete_side(cloud: &Cloud, sectors: Option<u64>) -> u32 {
    sectors.map_or_else(
        || crate::hpr::complete_side(cloud.len()),
        |k| crate::hpr::complete_grid((k as f64).sqrt().round() as u32),
    )
}

/// Exact HPR, its hull triangles longer than the request's edge limit dropped.
fn exact_visible_points(cloud: &Cloud, view: &HprView, request: &Request) -> Result<Found> {
    let mut visibility = crate::hpr::exact(&cloud.positions, view.camera.eye, request.radius)?;
    if let Some(max_edge) = request.max_edge {
        let pixel = |i: u32| view.pixel(cloud.positions[i as usize]);
        visibility
            .triangles
            .retain(|&t| approx::short_in_view(t, &pixel, max_edge));
    }
    Ok(Found {
        visibility,
        note: "method            exact HPR".into(),
        sectors: None,
    })
}

/// The sector approximation: its CPU reference, or its GPU passes with `request.gpu`.
fn sector_visible_points(cloud: &Cloud, view: &HprView, request: &Request) -> Result<Found> {
    let eye = view.camera.eye;
    let r = crate::hpr::flip_radius(&cloud.positions, eye, request.radius)?;
    let points: Vec<glam::DVec3> = cloud.positions.iter().map(|p| p.as_dvec3()).collect();
    let sphere = approx::bounding_sphere(&points).context("no points")?;
    let sqrt_k = match request.sectors {
        Some(k) => (k as f64)
            .sqrt()
            .round()
            .clamp(1.0, f64::from(MAX_SQRT_K * 2)) as u32,
        None => approx::sqrt_k_for_view(sphere, eye.as_dvec3(), view.pixel_angle(), MAX_SQRT_K),
    };
    let propagation = match (request.m, request.rounds) {
        (Some(m), _) => Propagation::Fixed(m),
        (None, Some(max_rounds)) => Propagation::Adaptive { max_rounds },
        (None, None) if request.gpu => Propagation::Adaptive { max_rounds: 256 },
        (None, None) => Propagation::UNTIL_STABLE,
    };
    if request.gpu {
        let complete = (request.algorithm == Algorithm::Complete)
            .then(|| complete_side(cloud, request.sectors));
        return gpu_visible_points(cloud, view, (r, sqrt_k, propagation), complete, request);
    }
    let params = Params {
        sqrt_k,
        radius: r,
        propagation,
    };
    let found =
        approx::approximate(&points, eye.as_dvec3(), params).map_err(|e| anyhow::anyhow!("{e}"))?;
    let partition = if found.full {
        "full sphere: the viewpoint is inside or near the bounding sphere"
    } else {
        "the bounding sphere's cone"
    };
    let capped = if found.capped { " (the cap)" } else { "" };
    let pixel = |i: u32| view.pixel(cloud.positions[i as usize]);
    let max_edge = request.max_edge.unwrap_or(f32::INFINITY);
    let triangles = approx::triangulate(&found.max, sqrt_k, pixel, max_edge);
    Ok(Found {
        visibility: crate::hpr::Visibility {
            visible: found.visible,
            triangles,
            radius: r,
            ..Default::default()
        },
        note: format!(
            "sectors           {sqrt_k} x {sqrt_k} over {partition}, {} propagation round(s){capped}, EMPTY grid 1/{} (CPU)",
            found.rounds, found.coarse
        ),
        sectors: Some(sqrt_k),
    })
}

/// The sector approximation on the GPU ([`evaluate`]) with flipping radius `radius`, √k
/// `sqrt_k` and `propagation` (with `complete`, the complete set on a finest grid of that many
/// sectors per angle decides), indices mapped back to the file's order.
fn gpu_visible_points(
    cloud: &Cloud,
    view: &HprView,
    (radius, sqrt_k, propagation): (f64, u32, Propagation),
    complete: Option<u32>,
    request: &Request,
) -> Result<Found> {
    let ctx = Arc::new(Context::new(&ContextOptions::from_env())?);
    let (scene, _) = upload(&ctx, cloud, &UploadOptions::default())?;
    // Stream order is the Morton order of the positions.
    let order = crate::point_streams::morton_order(&cloud.positions);
    let mut settings = Settings::grid(sqrt_k, radius, propagation, request.sort);
    settings.params.max_edge = request.max_edge.unwrap_or(f32::INFINITY);
    settings.params.complete_side = complete.unwrap_or(0);
    let found = evaluate(
        &ctx,
        &scene,
        (view.camera.view(), view.proj()),
        (view.width, view.height),
        &settings,
        true,
    )?;
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    let mut visible: Vec<u32> = found.visible.iter().map(|&i| order[i as usize]).collect();
    visible.sort_unstable();
    let triangles = found
        .triangles
        .iter()
        .map(|t| t.map(|i| order[i as usize]))
        .collect();
    let state = found.state;
    let capped = match propagation {
        Propagation::Adaptive { max_rounds } if state.rounds >= max_rounds => " (the cap)",
        _ => "",
    };
    Ok(Found {
        visibility: crate::hpr::Visibility {
            visible,
            triangles,
            radius,
            ..Default::default()
        },
        note: format!(
            "sectors           {0} x {0}{1}, {2} propagation round(s){capped}, EMPTY grid 1/{3} (GPU, {4})",
            state.sqrt_k,
            if state.full != 0 { " over the full sphere" } else { "" },
            state.rounds,
            state.coarse,
            if request.sort { "radix sort + segmented max" } else { "atomicMax" },
        ),
        sectors: Some(state.sqrt_k),
    })
}

/// The points of `cloud` visible from `eye` through the approximate hull `kind` over `k` cells
/// or sectors.
fn approximate_hull(
    cloud: &Cloud,
    eye: glam::Vec3,
    radius: Radius,
    kind: HullKind,
    k: u64,
) -> Result<Found> {
    use crate::hpr::hulls::Hull;
    let k = u32::try_from(k).map_err(|_| anyhow::anyhow!("--sectors {k} is too large"))?;
    let hull = match kind {
        HullKind::Bfp => Hull::Bfp { cells: k },
        HullKind::Kavan => Hull::Kavan { sectors: k },
        HullKind::Hybrid => Hull::Hybrid { sectors: k },
    };
    Ok(Found {
        visibility: crate::hpr::hulls::approximate_hull(&cloud.positions, eye, radius, hull)?,
        note: format!("method            approximate hull {hull:?} (003 ch. 3)"),
        sectors: None,
    })
}

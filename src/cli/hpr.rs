//! `surfel hpr` and `surfel hpr-study`: hidden point removal of a file from a viewpoint, exact
//! or approximate, on the CPU or the GPU, and the study comparing them.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use clap::Args;

use super::{context, InputArgs};
use crate::frame::{write_png, Channels, Size};
use crate::gpu_scene::{upload, UploadOptions};
use crate::scene::camera::parse_vec3;
use crate::scene::{load_prepared, Cloud};

#[derive(Args, Debug)]
pub struct HprArgs {
    /// Point cloud or mesh (any input format).
    pub file: PathBuf,
    /// Viewpoint X,Y,Z in the file's local frame (as `surfel info` prints bounds).
    #[arg(long)]
    pub eye: String,
    /// Exact HPR (convex hull of the spherically flipped points, 003 §2.1); otherwise the
    /// sector approximation of 003 ch. 4 (its CPU reference).
    #[arg(long)]
    pub exact: bool,
    /// An approximate convex hull of 003 ch. 3 in place of the exact one, over k = `--sectors`
    /// grid cells (bfp) or sphere sectors (kavan, hybrid).
    #[arg(long, value_enum, conflicts_with_all = ["exact", "m"])]
    pub hull: Option<HullKind>,
    /// The complete approximate visible set (`hpr::complete`, beyond 003): every point not
    /// certified inside a tetrahedron of the eye and three sector extremes on six grids, the
    /// finest `--sectors` (rounded up to a multiple of 32 per angle; default about four sectors
    /// per point).
    #[arg(long, conflicts_with_all = ["exact", "hull", "m"])]
    pub complete: bool,
    /// Sectors k of the approximation (rounded to a square √k × √k grid; `--hull`: its k);
    /// by default one sector per pixel of the bounding sphere's projection in the `--size`
    /// view (`--hull`: 65,536).
    #[arg(long)]
    pub sectors: Option<u64>,
    /// Fixed propagation over an m × m window (odd); adaptive propagation without it.
    #[arg(long)]
    pub m: Option<u32>,
    /// Adaptive propagation: at most this many rounds (reported when reached); default: until
    /// stable on the CPU, 256 rounds on the GPU.
    #[arg(long)]
    pub rounds: Option<u32>,
    /// Run the sector approximation on the GPU (compute passes of `methods::hpr`).
    #[arg(long, conflicts_with_all = ["exact", "hull"])]
    pub gpu: bool,
    /// With `--gpu`: the thesis' radix sort by sector and segmented maximum instead of the
    /// sort-free 64-bit atomicMax.
    #[arg(long, requires = "gpu")]
    pub sort: bool,
    /// The point the view looks at (default: the bounding sphere's centre).
    #[arg(long)]
    pub target: Option<String>,
    /// Drop triangles with an edge longer than this many pixels of the `--size` view: the
    /// approximation's reconstruction (003 §4.4; default 10) and, when given, exact HPR's hull
    /// triangles (003 §2.2; default: all of them).
    #[arg(long)]
    pub max_edge: Option<f32>,
    /// The view from the eye towards the target that sectors, edge lengths, true visibility
    /// and `--out *.png` are measured in (the thesis' 900 x 900).
    #[arg(long, default_value = "900x900")]
    pub size: String,
    /// Also run exact HPR and print the result's precision, recall and F1 against it; for an
    /// input with faces, also against the true visibility of its vertices (the mesh's depth
    /// buffer in the `--size` view).
    #[arg(long)]
    pub compare: bool,
    /// Flipping radius R as a factor of the cloud's diameter (default: R from the sampling
    /// density, `hpr::Radius::Density`).
    #[arg(long, conflicts_with = "radius")]
    pub radius_factor: Option<f64>,
    /// Flipping radius R in scene units.
    #[arg(long)]
    pub radius: Option<f64>,
    /// Print one JSON line of the numbers (for scripts and the HPR report).
    #[arg(long)]
    pub json: bool,
    /// Write the visible points and the triangles over them (exact, `--hull bfp|hybrid`: the
    /// hull's; the sector approximation: its reconstruction's; `--hull kavan`: none) as binary
    /// PLY, or (`.png`) render them in the `--size` view (triangles where there are any).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
}

#[derive(Args, Debug)]
pub struct HprStudyArgs {
    /// Output folder (report.md, results.json, charts).
    #[arg(long, default_value = "docs/reports/lavapipe-hpr")]
    pub out: PathBuf,
    /// Models as NAME=PATH (meshes give true visibility).
    #[arg(long = "model", value_name = "NAME=PATH", required = true)]
    pub models: Vec<String>,
    /// The mesh sampled for the time-against-points series.
    #[arg(long)]
    pub sampled: PathBuf,
    /// Point counts of that series.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "50000,200000,1000000,5000000"
    )]
    pub counts: Vec<usize>,
    /// The view's size.
    #[arg(long, default_value = "900x900")]
    pub size: String,
    /// GPU frames timed per configuration.
    #[arg(long, default_value_t = 5)]
    pub frames: u32,
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

/// What `visible_points` found.
pub(super) struct Found {
    pub(super) visibility: crate::hpr::Visibility,
    /// How the points were found.
    pub(super) note: String,
    /// The sector approximation's √k.
    sectors: Option<u32>,
}

/// How the sector approximation runs.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SectorOptions {
    /// √k; `None`: from the view.
    sqrt_k: Option<u32>,
    m: Option<u32>,
    rounds: Option<u32>,
    gpu: bool,
    sort: bool,
    /// The reconstruction's longest projected edge in pixels (`None`: no limit).
    max_edge: Option<f32>,
    /// On the GPU, the complete visible set with this many sectors per angle on its finest
    /// grid in place of the distinct extremes.
    complete: Option<u32>,
}

/// The approximation's reconstruction drops edges longer than this many pixels by default.
const DEFAULT_MAX_EDGE: f32 = 10.0;

/// The largest √k the approximation allocates when k comes from the view.
const MAX_SQRT_K: u32 = 4096;

/// The points of `cloud` visible from the view's eye.
pub(super) fn visible_points(
    cloud: &Cloud,
    view: &crate::eval::hpr_view::HprView,
    mode: Visibility,
    radius: crate::hpr::Radius,
    options: SectorOptions,
) -> Result<Found> {
    use crate::hpr::approx::{self, Params, Propagation};
    let eye = view.camera.eye;
    let pixel = |i: u32| view.pixel(cloud.positions[i as usize]);
    let max_edge = options.max_edge.unwrap_or(f32::INFINITY);
    if mode == Visibility::HprExact {
        let mut visibility = crate::hpr::exact(&cloud.positions, eye, radius)?;
        if options.max_edge.is_some() {
            visibility
                .triangles
                .retain(|&t| approx::short_in_view(t, &pixel, max_edge));
        }
        return Ok(Found {
            visibility,
            note: "method            exact HPR".into(),
            sectors: None,
        });
    }
    let r = crate::hpr::flip_radius(&cloud.positions, eye, radius)?;
    let points: Vec<glam::DVec3> = cloud.positions.iter().map(|p| p.as_dvec3()).collect();
    let sphere = approx::bounding_sphere(&points).context("no points")?;
    let sqrt_k = options.sqrt_k.unwrap_or_else(|| {
        approx::sqrt_k_for_view(sphere, eye.as_dvec3(), view.pixel_angle(), MAX_SQRT_K)
    });
    let propagation = match (options.m, options.rounds) {
        (Some(m), _) => Propagation::Fixed(m),
        (None, Some(max_rounds)) => Propagation::Adaptive { max_rounds },
        (None, None) if options.gpu => Propagation::Adaptive { max_rounds: 256 },
        (None, None) => Propagation::UNTIL_STABLE,
    };
    if options.gpu {
        return gpu_visible_points(cloud, view, r, sqrt_k, propagation, options);
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

/// `visible_points` on the GPU (`methods::hpr::evaluate`), indices mapped back to the file's
/// order.
fn gpu_visible_points(
    cloud: &Cloud,
    view: &crate::eval::hpr_view::HprView,
    radius: f64,
    sqrt_k: u32,
    propagation: crate::hpr::approx::Propagation,
    options: SectorOptions,
) -> Result<Found> {
    use crate::hpr::approx::Propagation;
    let ctx = context(false)?;
    let (scene, _) = upload(&ctx, cloud, &UploadOptions::default())?;
    // Stream order is the Morton order of the positions.
    let order = crate::point_streams::morton_order(&cloud.positions);
    let mut settings =
        crate::methods::hpr::Settings::grid(sqrt_k, radius, propagation, options.sort);
    settings.params.max_edge = options.max_edge.unwrap_or(f32::INFINITY);
    settings.params.complete_side = options.complete.unwrap_or(0);
    let found = crate::methods::hpr::evaluate(
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
            if options.sort { "radix sort + segmented max" } else { "atomicMax" },
        ),
        sectors: Some(state.sqrt_k),
    })
}

/// The points of `cloud` visible from `eye` through the approximate hull `kind` over `k` cells
/// or sectors.
fn approximate_hull(
    cloud: &Cloud,
    eye: glam::Vec3,
    radius: crate::hpr::Radius,
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

pub(super) fn hpr(a: HprArgs) -> Result<()> {
    let eye = glam::Vec3::from(parse_vec3(&a.eye).map_err(anyhow::Error::msg)?);
    let target = a
        .target
        .as_deref()
        .map(|t| {
            parse_vec3(t)
                .map(glam::Vec3::from)
                .map_err(anyhow::Error::msg)
        })
        .transpose()?;
    let cloud = load_prepared(&a.file, &a.input.options(true))?;
    let radius = match (a.radius, a.radius_factor) {
        (Some(r), _) => crate::hpr::Radius::Absolute(r),
        (None, Some(f)) => crate::hpr::Radius::Factor(f),
        (None, None) => crate::hpr::Radius::Density {
            spacing: crate::hpr::spacing(&cloud),
        },
    };
    let view = crate::eval::hpr_view::HprView::new(
        &cloud,
        eye,
        target,
        Size::parse(&a.size).map_err(anyhow::Error::msg)?.pair(),
    );
    let start = std::time::Instant::now();
    let mode = if a.exact {
        Visibility::HprExact
    } else {
        Visibility::Hpr
    };
    let found = match a.hull {
        Some(kind) => approximate_hull(&cloud, eye, radius, kind, a.sectors.unwrap_or(65_536)),
        None if a.complete && !a.gpu => {
            let side = a.sectors.map_or_else(
                || crate::hpr::complete_side(cloud.len()),
                |k| crate::hpr::complete_grid((k as f64).sqrt().round() as u32),
            );
            crate::hpr::complete(&cloud.positions, eye, radius, Some(side)).map(|visibility| {
                Found {
                    note: format!(
                        "method            complete visible set, {side} sectors per angle, {} grids",
                        crate::hpr::prefilter::LEVELS
                    ),
                    visibility,
                    sectors: Some(side),
                }
            })
        }
        None => {
            let sqrt_k = a.sectors.map(|k| {
                (k as f64)
                    .sqrt()
                    .round()
                    .clamp(1.0, f64::from(MAX_SQRT_K * 2)) as u32
            });
            let options = SectorOptions {
                sqrt_k,
                m: a.m,
                rounds: a.rounds,
                gpu: a.gpu,
                sort: a.sort,
                max_edge: a.max_edge.or((!a.exact).then_some(DEFAULT_MAX_EDGE)),
                complete: a.complete.then(|| {
                    a.sectors.map_or_else(
                        || crate::hpr::complete_side(cloud.len()),
                        |k| crate::hpr::complete_grid((k as f64).sqrt().round() as u32),
                    )
                }),
            };
            visible_points(&cloud, &view, mode, radius, options)
        }
    };
    let Found {
        visibility: v,
        note,
        sectors,
    } = found.with_context(|| a.file.display().to_string())?;
    let seconds = start.elapsed().as_secs_f64();
    let mut report = serde_json::json!({
        "file": a.file.display().to_string(),
        "points": cloud.len(),
        "visible": v.visible.len(),
        "triangles": v.triangles.len(),
        "radius": v.radius,
        "seconds": seconds,
        "sqrt_k": sectors,
    });
    if !a.json {
        println!("{note}");
        println!("points            {}", cloud.len());
        println!(
            "visible           {} ({:.1} %)",
            v.visible.len(),
            100.0 * v.visible.len() as f64 / cloud.len().max(1) as f64
        );
        println!("triangles         {}", v.triangles.len());
        println!("radius R          {}", v.radius);
        println!("at the viewpoint  {}", v.at_viewpoint);
        if v.joggled {
            println!("joggled           yes (flat input: Qhull QJ)");
        }
        println!("time              {seconds:.3} s");
    }
    if a.compare {
        let start = std::time::Instant::now();
        let truth = crate::hpr::exact(&cloud.positions, eye, radius)?;
        let exact_s = start.elapsed().as_secs_f64();
        let (p, r, f1) = crate::hpr::agreement(&v.visible, &truth.visible);
        report["exact"] = serde_json::json!({
            "visible": truth.visible.len(), "seconds": exact_s,
            "precision": p, "recall": r, "f1": f1,
        });
        if !a.json {
            println!(
                "against exact     precision {p:.4}, recall {r:.4}, F1 {f1:.4} ({} exactly visible, {exact_s:.3} s)",
                truth.visible.len()
            );
        }
        if cloud.faces.is_some() {
            let seen = crate::eval::hpr_view::mesh_visibility(&cloud, &view)?;
            let (p, r, f1) = crate::hpr::agreement(&v.visible, &seen);
            let (ep, er, ef1) = crate::hpr::agreement(&truth.visible, &seen);
            report["truth"] = serde_json::json!({
                "visible": seen.len(), "precision": p, "recall": r, "f1": f1,
                "exact_precision": ep, "exact_recall": er, "exact_f1": ef1,
            });
            if !a.json {
                println!(
                    "against the mesh  precision {p:.4}, recall {r:.4}, F1 {f1:.4} ({} vertices seen in its depth buffer; exact HPR: {ep:.4}, {er:.4}, {ef1:.4})",
                    seen.len()
                );
            }
        }
    }
    if a.json {
        println!("{report}");
    }
    if let Some(out) = &a.out {
        let visible = crate::hpr::visible_cloud(&cloud, &v);
        if crate::scene::format_extension(out) == "png" {
            render_hpr_png(&visible, &view, out)?;
        } else {
            crate::scene::ply::save(out, &visible)
                .with_context(|| format!("{}: cannot write", out.display()))?;
        }
        if !a.json {
            println!(
                "written           {} ({} points)",
                out.display(),
                visible.len()
            );
        }
    }
    Ok(())
}

/// Renders `cloud` (the visible points, with the reconstruction's faces when it has any) in
/// `view` to a PNG: the faces as a mesh, else the points by the compute rasterizer.
fn render_hpr_png(cloud: &Cloud, view: &crate::eval::hpr_view::HprView, out: &Path) -> Result<()> {
    let method = if cloud.faces.is_some() {
        "mesh:samples=1"
    } else {
        "compute"
    };
    let frame = crate::eval::hpr_view::render_once(cloud, view, method)?;
    write_png(out, &frame, Channels::Rgba)
        .with_context(|| format!("{}: cannot write", out.display()))
}

pub(super) fn hpr_study(a: HprStudyArgs) -> Result<()> {
    let models = a
        .models
        .iter()
        .map(|m| {
            m.split_once('=')
                .map(|(n, p)| (n.to_string(), PathBuf::from(p)))
                .with_context(|| format!("--model {m}: expected NAME=PATH"))
        })
        .collect::<Result<Vec<_>>>()?;
    let options = crate::eval::hpr::StudyOptions {
        models,
        sampled: a.sampled,
        counts: a.counts,
        size: Size::parse(&a.size).map_err(anyhow::Error::msg)?.pair(),
        frames: a.frames,
    };
    let rows = crate::eval::hpr::run(&options)?;
    let ctx = context(false)?;
    crate::eval::hpr::write_report(&rows, &ctx.caps.device_name, options.size, &a.out)?;
    eprintln!(
        "{} rows -> {}",
        rows.len(),
        a.out.join("report.md").display()
    );
    Ok(())
}

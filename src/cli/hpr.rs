//! `surfel hpr` and `surfel hpr-study`: hidden point removal of a file from a viewpoint, exact
//! or approximate, on the CPU or the GPU (found by `methods::hpr::visible`), and the study
//! comparing them (`eval::hpr`): their arguments, what they print and the files they write.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use clap::Args;

use super::{context, InputArgs};
use crate::eval::hpr::{mesh_visibility, render_once};
use crate::frame::{write_png, Channels, Size};
use crate::hpr::view::HprView;
use crate::hpr::Radius;
use crate::methods::hpr::visible::{
    visible_points, Algorithm, Found, HullKind, Request, DEFAULT_MAX_EDGE,
};
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

impl HprArgs {
    /// What the flags ask [`visible_points`] for, with flipping radius `radius`.
    fn request(&self, radius: Radius) -> Request {
        let algorithm = match self.hull {
            Some(kind) => Algorithm::Hull(kind),
            None if self.exact => Algorithm::Exact,
            None if self.complete => Algorithm::Complete,
            None => Algorithm::Sectors,
        };
        Request {
            sectors: self.sectors,
            m: self.m,
            rounds: self.rounds,
            gpu: self.gpu,
            sort: self.sort,
            max_edge: self.max_edge.or((!self.exact).then_some(DEFAULT_MAX_EDGE)),
            ..Request::new(algorithm, radius)
        }
    }
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
        (Some(r), _) => Radius::Absolute(r),
        (None, Some(f)) => Radius::Factor(f),
        (None, None) => Radius::Density {
            spacing: crate::hpr::spacing(&cloud),
        },
    };
    let view = HprView::new(
        &cloud,
        eye,
        target,
        Size::parse(&a.size).map_err(anyhow::Error::msg)?.pair(),
    );
    let start = std::time::Instant::now();
    let Found {
        visibility: v,
        note,
        sectors,
    } = visible_points(&cloud, &view, &a.request(radius))
        .with_context(|| a.file.display().to_string())?;
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
        compare((&cloud, &view), radius, &v.visible, a.json, &mut report)?;
    }
    if a.json {
        println!("{report}");
    }
    if let Some(out) = &a.out {
        let visible = crate::hpr::visible_cloud(&cloud, &v);
        write_visible(&visible, &view, out)?;
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

/// `--compare`: `visible` scored against exact HPR and, for an input with faces, against the
/// true visibility of its vertices, added to `report` and printed unless `json`.
fn compare(
    (cloud, view): (&Cloud, &HprView),
    radius: Radius,
    visible: &[u32],
    json: bool,
    report: &mut serde_json::Value,
) -> Result<()> {
    let start = std::time::Instant::now();
    let truth = crate::hpr::exact(&cloud.positions, view.camera.eye, radius)?;
    let exact_s = start.elapsed().as_secs_f64();
    let (p, r, f1) = crate::hpr::agreement(visible, &truth.visible);
    report["exact"] = serde_json::json!({
        "visible": truth.visible.len(), "seconds": exact_s,
        "precision": p, "recall": r, "f1": f1,
    });
    if !json {
        println!(
            "against exact     precision {p:.4}, recall {r:.4}, F1 {f1:.4} ({} exactly visible, {exact_s:.3} s)",
            truth.visible.len()
        );
    }
    if cloud.faces.is_some() {
        let seen = mesh_visibility(cloud, view)?;
        let (p, r, f1) = crate::hpr::agreement(visible, &seen);
        let (ep, er, ef1) = crate::hpr::agreement(&truth.visible, &seen);
        report["truth"] = serde_json::json!({
            "visible": seen.len(), "precision": p, "recall": r, "f1": f1,
            "exact_precision": ep, "exact_recall": er, "exact_f1": ef1,
        });
        if !json {
            println!(
                "against the mesh  precision {p:.4}, recall {r:.4}, F1 {f1:.4} ({} vertices seen in its depth buffer; exact HPR: {ep:.4}, {er:.4}, {ef1:.4})",
                seen.len()
            );
        }
    }
    Ok(())
}

/// Writes `cloud` (the visible points, with the reconstruction's faces when it has any) as
/// PLY or, to a `.png`, rendered in `view`: the faces as a mesh, else the points by the compute
/// rasterizer.
fn write_visible(cloud: &Cloud, view: &HprView, out: &Path) -> Result<()> {
    if crate::scene::format_extension(out) != "png" {
        return crate::scene::ply::save(out, cloud)
            .with_context(|| format!("{}: cannot write", out.display()));
    }
    let method = if cloud.faces.is_some() {
        "mesh:samples=1"
    } else {
        "compute"
    };
    let frame = render_once(cloud, view, method)?;
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

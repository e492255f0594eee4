//! The command line: `surfel render | view | info | sample | convert | vpc | convert-lines | hpr |
//! hpr-study | bench | report`, one module per subcommand.

mod bench;
mod convert;
mod convert_lines;
mod hpr;
mod info;
mod render;
mod sample;
mod view;
mod vpc;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand};

use crate::gpu::{Context, ContextOptions};
use crate::post::{Background, Edl, PostOptions, EDL_DEFAULT_ARG};
use crate::render::settings::ViewSettings;
use crate::scene::camera::{parse_dvec3, Pose, Up};
use crate::scene::preprocess;
use crate::scene::scene_file::SceneFile;
use crate::scene::{Cloud, Light, LoadOptions};
pub use bench::{BenchArgs, ReportArgs};
pub use convert::ConvertArgs;
pub use convert_lines::ConvertLinesArgs;
pub use hpr::{HprArgs, HprStudyArgs};
pub use info::InfoArgs;
pub use render::RenderArgs;
pub use sample::SampleArgs;
pub use view::ViewArgs;
pub use vpc::VpcArgs;

/// surfel: a Vulkan point-cloud renderer.
#[derive(Parser, Debug)]
#[command(name = "surfel", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render FILE headless to a PNG (no window system needed).
    Render(RenderArgs),
    /// Open FILE in the interactive viewer.
    View(ViewArgs),
    /// Print counts, attributes, bounds, GPU memory per point and device capabilities.
    Info(InfoArgs),
    /// Sample a mesh into a point cloud (area-weighted, face normals, radii from density).
    Sample(SampleArgs),
    /// Convert files, folders or patterns to one COPC file (octree of LAZ chunks) for
    /// streaming, or each to its own COPC tile listed in a .vpc (--tiles).
    Convert(ConvertArgs),
    /// Write a virtual point cloud (.vpc) listing COPC files, from their headers.
    Vpc(VpcArgs),
    /// Convert a mesh's thin parts (leaves, branches) into ribbons and tubes (thesis 000 §5.1).
    ConvertLines(ConvertLinesArgs),
    /// Hidden point removal: the points of FILE visible from a viewpoint (003).
    Hpr(HprArgs),
    /// The HPR report: visible points against k, precision/recall/F1 against exact HPR and
    /// true visibility, time against points, R and noise sweeps, the partial reconstruction.
    HprStudy(HprStudyArgs),
    /// Run a benchmark sweep: GPU timings and accuracy against the ground truth, with charts.
    Bench(BenchArgs),
    /// Write report.md (tables and charts) and results.csv from a sweep's results.json.
    Report(ReportArgs),
}

/// Input and preprocessing options shared by the commands that load a model.
#[derive(Args, Debug, Clone)]
pub struct InputArgs {
    /// Neighbours for k-NN normals and radii (estimated only for methods that read them);
    /// 0 turns the estimation off; at most 256.
    #[arg(long, default_value_t = preprocess::DEFAULT_K, value_parser = neighbours)]
    pub k: usize,
    /// Reuse/store computed normals and radii in FILE.surfel-cache.
    #[arg(long)]
    pub cache: bool,
    /// COPC only: read whole octree levels from the root down while their points fit N (the
    /// root level always). To draw a COPC by view instead: --stream and --point-budget.
    #[arg(long = "level-budget", value_name = "N")]
    pub budget: Option<u64>,
    /// Text files (.xyz, .txt, .pts, .csv) without a row of column names: name the columns,
    /// e.g. x,y,z,intensity,red,green,blue (`_` skips one).
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
}

/// Parses `--k`: 0 to [`preprocess::MAX_K`] neighbours.
fn neighbours(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(k) if k <= preprocess::MAX_K => Ok(k),
        _ => Err(format!(
            "expected 0 to {} neighbours, found \"{text}\"",
            preprocess::MAX_K
        )),
    }
}

impl InputArgs {
    /// The loading options these flags select; `estimate`: compute the normals and radii a
    /// file lacks (for a method with `needs_surfels`).
    pub fn options(&self, estimate: bool) -> LoadOptions {
        LoadOptions {
            k: self.k,
            estimate,
            cache: self.cache,
            budget: self.budget,
            columns: self.columns.clone(),
        }
    }
}

/// Camera and light options.
#[derive(Args, Debug, Clone)]
pub struct CameraArgs {
    /// Orbit around the bounding-sphere centre: AZ,EL[,DISTANCE] in degrees (distance scales the
    /// framing distance).
    #[arg(long, value_name = "AZ,EL", allow_hyphen_values = true)]
    pub orbit: Option<String>,
    /// Eye position X,Y,Z (needs --target).
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        requires = "target"
    )]
    pub eye: Option<String>,
    /// Look-at point X,Y,Z (needs --eye).
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        requires = "eye"
    )]
    pub target: Option<String>,
    /// The axis pointing up in the data (x, y, z, -x, -y, -z): orbits turn about it. Default:
    /// z for LAS, LAZ, COPC, E57 and PCD, y for the other formats.
    #[arg(long, value_name = "AXIS", allow_hyphen_values = true, value_parser = parse_up)]
    pub up: Option<Up>,
    /// Scene file (TOML/JSON) with an up axis, a camera pose and lights.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Render with the base color instead of the points' colors.
    #[arg(long)]
    pub no_color: bool,
    /// Color by a field: rgb, none, elevation, normal, intensity, classification, return, or
    /// any scalar field by name (also scalar:NAME); `surfel info` lists a file's fields.
    #[arg(long, value_name = "NAME")]
    pub color_by: Option<String>,
    #[command(flatten)]
    pub post: PostArgs,
}

/// Post-processing options (after any method; see `post`).
#[derive(Args, Debug, Clone, Default)]
pub struct PostArgs {
    /// Eye-dome lighting, depth-based shading that needs no normals: `--edl` alone for
    /// strength 1 and radius 1.4 pixels, or `--edl STRENGTH[,RADIUS]`.
    #[arg(
        long,
        value_name = "STRENGTH[,RADIUS]",
        num_args = 0..=1,
        default_missing_value = EDL_DEFAULT_ARG,
        value_parser = Edl::parse
    )]
    pub edl: Option<Edl>,
    /// Background of uncovered pixels: #rrggbb, r,g,b (0-255), black, white, grey, or
    /// transparent (alpha 0 in the PNG). Default: opaque black.
    #[arg(long, value_name = "COLOR", value_parser = Background::parse)]
    pub background: Option<Background>,
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(a) => render::render(a),
        Command::View(a) => view::view(a),
        Command::Info(a) => info::info(a),
        Command::Sample(a) => sample::sample(a),
        Command::Convert(a) => convert::convert(a),
        Command::Vpc(a) => vpc::vpc(a),
        Command::ConvertLines(a) => convert_lines::convert_lines(a),
        Command::Hpr(a) => hpr::hpr(a),
        Command::HprStudy(a) => hpr::hpr_study(a),
        Command::Bench(a) => bench::bench(a),
        Command::Report(a) => bench::report(a),
    }
}

/// Parses `--up`.
fn parse_up(s: &str) -> Result<Up, String> {
    s.parse()
}

/// The view settings from the camera options (scene file first, flags override).
pub fn view_settings(cam: &CameraArgs) -> Result<ViewSettings> {
    let file = match &cam.scene {
        Some(p) => SceneFile::load(p)?,
        None => SceneFile::default(),
    };
    let mut pose = file.camera;
    if let Some(o) = &cam.orbit {
        pose = Pose::parse_orbit(o).map_err(anyhow::Error::msg)?;
    }
    if let (Some(eye), Some(target)) = (&cam.eye, &cam.target) {
        pose = Some(Pose::LookAt {
            eye: parse_dvec3(eye).map_err(anyhow::Error::msg)?,
            target: parse_dvec3(target).map_err(anyhow::Error::msg)?,
        });
    }
    if let Some(pose) = &pose {
        pose.check().map_err(anyhow::Error::msg)?;
    }
    let filter = file.filter();
    let lights = if file.lights.is_empty() {
        vec![Light::headlight()]
    } else {
        file.lights
    };
    Ok(ViewSettings {
        pose,
        up: cam.up.or(file.up),
        lights,
        post: PostOptions {
            edl: cam.post.edl.or(file.edl),
            background: cam
                .post
                .background
                .or(file.background)
                .unwrap_or(Background::DEFAULT),
        },
        filter,
        bookmarks: file.bookmarks,
        color_by: cam.color_by.clone().or(file.color_by),
        inputs: file.inputs,
    })
}

/// Whether normals and radii the file lacks are estimated: for a method that reads them, and
/// for coloring by normal.
fn estimates(method: &crate::methods::MethodInfo, settings: &ViewSettings) -> bool {
    method.needs_surfels || settings.color_by.as_deref() == Some("normal")
}

/// The error for a method that reads normals and radii the cloud does not have (the file has
/// none and `--k 0` turned their estimation off).
fn check_surfels(method: &crate::methods::MethodInfo, cloud: &Cloud, file: &Path) -> Result<()> {
    if method.needs_surfels && (cloud.normals.is_none() || cloud.radii.is_none()) {
        bail!(
            "{}: {} reads per-point normals and radii; the file has none and --k 0 turns their \
             estimation off (use --k 10, or a method that draws raw positions: points, compute)",
            file.display(),
            method.name
        );
    }
    Ok(())
}

fn context(validation: bool) -> Result<Arc<Context>> {
    let mut options = ContextOptions::from_env();
    options.validation |= validation;
    Ok(Arc::new(Context::new(&options)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;
    use clap::CommandFactory;
    use glam::Vec3;

    #[test]
    fn every_subcommand_s_flags_are_distinct() {
        // No two arguments of one subcommand share a long name or alias (`hpr` takes both
        // `--k`, the neighbours of the estimate, and `--sectors`).
        for sub in Cli::command().get_subcommands() {
            let mut seen = std::collections::BTreeSet::new();
            for arg in sub.get_arguments() {
                let aliases = arg.get_all_aliases().unwrap_or_default();
                for name in arg.get_long().into_iter().chain(aliases) {
                    assert!(
                        seen.insert(name),
                        "surfel {}: --{name} names two arguments",
                        sub.get_name()
                    );
                }
            }
        }
    }

    fn camera_args(orbit: Option<&str>, up: Option<Up>) -> CameraArgs {
        CameraArgs {
            orbit: orbit.map(str::to_owned),
            eye: None,
            target: None,
            up,
            scene: None,
            no_color: false,
            post: PostArgs::default(),
            color_by: None,
        }
    }

    #[test]
    fn the_up_axis_picks_the_default_pose_and_an_explicit_choice_wins() {
        let (c, r) = (Vec3::new(1.0, 2.0, 3.0), 4.0);
        let none = view_settings(&camera_args(None, None)).expect("settings");
        assert_eq!(
            none.camera(c, r, Up::Y, glam::DVec3::ZERO),
            Camera::framing(c, r)
        );
        assert_eq!(
            none.camera(c, r, Up::Z, glam::DVec3::ZERO),
            Camera::orbit_about(Up::Z, c, r, 30.0, 35.0, 1.0)
        );
        let forced = view_settings(&camera_args(Some("default"), Some(Up::Y))).expect("settings");
        assert_eq!(
            forced.camera(c, r, Up::Z, glam::DVec3::ZERO),
            Camera::framing(c, r)
        );
        let orbit = view_settings(&camera_args(Some("0,84"), Some(Up::Z))).expect("settings");
        assert_eq!(
            orbit.camera(c, r, Up::Y, glam::DVec3::ZERO),
            Camera::orbit_about(Up::Z, c, r, 0.0, 84.0, 1.0)
        );
    }
}

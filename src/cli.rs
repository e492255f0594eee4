//! The command line: `surfel render | view | info | sample | convert-lines | bench | report`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use clap::{Args, Parser, Subcommand};
use serde::Serialize;

use crate::color::{self, Coloring};
use crate::estimate::EstimateOn;
use crate::gpu::{Context, ContextOptions, ScopeStats};
use crate::methods::{MethodConfig, METHODS};
use crate::post::{Background, Edl, PostOptions, EDL_DEFAULT_ARG};
use crate::render::{upload_for, Extras, Renderer, View};
use crate::scene::camera::{parse_vec3, Pose, Up};
use crate::scene::compose::{self, SceneInput};
use crate::scene::preprocess;
use crate::scene::scene_file::SceneFile;
use crate::scene::{load_prepared, Cloud, Estimator, Light, LoadOptions};

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
    /// Convert a mesh's thin parts (leaves, branches) into ribbons and tubes (thesis 000 §5.1).
    ConvertLines(ConvertLinesArgs),
    /// Hidden point removal: the points of FILE visible from a viewpoint (003).
    Hpr(HprArgs),
    /// The HPR report: visible points against k, precision/recall/F1 against exact HPR and
    /// true visibility, time against points, R and noise sweeps, the partial reconstruction.
    HprStudy(HprStudyArgs),
    /// Run a benchmark sweep: GPU timings and accuracy against the ground truth, with charts.
    Bench(BenchArgs),
    /// Write report.md (tables and charts) from a sweep's results.json.
    Report(ReportArgs),
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Sweep file (TOML); see benches/sweeps/.
    #[arg(required_unless_present = "quick")]
    pub sweep: Option<PathBuf>,
    /// Run the tiny built-in sweep (benches/sweeps/quick.toml), suitable for CI on lavapipe.
    #[arg(long, conflicts_with = "sweep")]
    pub quick: bool,
    /// Output folder for results.json, results.csv and charts/.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
    /// Also write report.md into the output folder.
    #[arg(long)]
    pub report: bool,
    #[arg(long)]
    pub validation: bool,
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// results.json written by `surfel bench`.
    pub results: PathBuf,
    /// Output folder (default: the folder of results.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
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
    /// root level always).
    #[arg(long, value_name = "N")]
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
    /// Directory for `P` screenshots (surfel-<n>.png; default: the current directory).
    #[arg(long)]
    pub screenshot_dir: Option<PathBuf>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub camera: CameraArgs,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    pub file: PathBuf,
    /// Skip the GPU capability report.
    #[arg(long)]
    pub no_device: bool,
    /// The axis pointing up in the data (x, y, z, -x, -y, -z). Default: the format's.
    #[arg(long, value_name = "AXIS", allow_hyphen_values = true, value_parser = parse_up)]
    pub up: Option<Up>,
    #[command(flatten)]
    pub input: InputArgs,
}

#[derive(Args, Debug)]
pub struct SampleArgs {
    /// Mesh with faces (ply, obj).
    pub mesh: PathBuf,
    /// Number of points.
    #[arg(long)]
    pub points: usize,
    /// Output binary PLY.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

#[derive(Args, Debug)]
pub struct ConvertLinesArgs {
    /// Polygon mesh (obj; materials from its mtllib give the colours).
    pub mesh: PathBuf,
    /// Write the line model (ASCII PLY: vertices, polylines, kept triangles) to FILE.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

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
    #[arg(long, alias = "k")]
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
    #[arg(long, default_value = "docs/report-lavapipe-hpr")]
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

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(a) => render(a),
        Command::View(a) => view(a),
        Command::Info(a) => info(a),
        Command::Sample(a) => sample(a),
        Command::ConvertLines(a) => convert_lines(a),
        Command::Hpr(a) => hpr(a),
        Command::HprStudy(a) => hpr_study(a),
        Command::Bench(a) => bench(a),
        Command::Report(a) => report(a),
    }
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("size '{s}': expected WxH, e.g. 1024x768"))?;
    let w: u32 = w
        .trim()
        .parse()
        .with_context(|| format!("size '{s}': bad width"))?;
    let h: u32 = h
        .trim()
        .parse()
        .with_context(|| format!("size '{s}': bad height"))?;
    if w == 0 || h == 0 || w > crate::render::MAX_EDGE || h > crate::render::MAX_EDGE {
        bail!(
            "size '{s}': each edge must be 1..={}",
            crate::render::MAX_EDGE
        );
    }
    Ok((w, h))
}

/// Parses `--up`.
fn parse_up(s: &str) -> Result<Up, String> {
    s.parse()
}

/// What the camera options select; unset fields fall back to the loaded cloud's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSettings {
    /// The pose, `None` for the up axis's default pose.
    pub pose: Option<Pose>,
    /// The up axis, `None` for the input format's.
    pub up: Option<Up>,
    pub lights: Vec<Light>,
    /// Eye-dome lighting and background (flags over the scene file over the defaults).
    pub post: PostOptions,
    /// The field to color by, `None` for the default (`color::default_field`).
    pub color_by: Option<String>,
    /// The scene file's extra inputs (hybrid scenes).
    pub inputs: Vec<SceneInput>,
}

impl ViewSettings {
    /// The up axis for a cloud whose format uses `format_up`.
    pub fn up(&self, format_up: Up) -> Up {
        self.up.unwrap_or(format_up)
    }

    /// The coloring of `cloud` (whose format uses `format_up`) these settings select; an unknown
    /// field is an error naming `file` and listing the cloud's fields.
    pub fn coloring(&self, file: &Path, cloud: &crate::scene::Cloud) -> Result<Coloring> {
        let name = self
            .color_by
            .as_deref()
            .unwrap_or_else(|| color::default_field(cloud));
        color::select(cloud, name, self.up(cloud.up))
            .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))
    }

    /// The camera for a cloud with this bounding sphere whose format uses `format_up`.
    pub fn camera(&self, centre: glam::Vec3, radius: f32, format_up: Up) -> crate::scene::Camera {
        let up = self.up(format_up);
        self.pose
            .unwrap_or_else(|| up.default_pose())
            .camera(centre, radius, up)
    }
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
            eye: parse_vec3(eye).map_err(anyhow::Error::msg)?,
            target: parse_vec3(target).map_err(anyhow::Error::msg)?,
        });
    }
    if let Some(pose) = &pose {
        pose.check().map_err(anyhow::Error::msg)?;
    }
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
        color_by: cam.color_by.clone().or(file.color_by),
        inputs: file.inputs,
    })
}

/// Loads `file` and merges the scene's extra inputs into it (`scene::compose`), each completed
/// by `scene::complete_with` and `estimate` before the merge; also the seconds spent
/// estimating normals and radii.
pub fn load_scene(
    file: &Path,
    settings: &ViewSettings,
    options: &LoadOptions,
    estimate: Estimator,
) -> Result<(Cloud, f64)> {
    let mut estimate_s = 0.0;
    let mut load = |path: &Path| -> Result<Cloud> {
        let mut cloud = crate::scene::load_with(path, &options.read())?;
        let start = std::time::Instant::now();
        if crate::scene::complete_with(&mut cloud, path, options, estimate)? {
            estimate_s += start.elapsed().as_secs_f64();
        }
        Ok(cloud)
    };
    let mut cloud = load(file)?;
    for input in &settings.inputs {
        let name = input.path.display().to_string();
        let mut other = compose::with_role(load(&input.path)?, input.role, &name)?;
        compose::transform(
            &mut other,
            input.scale.unwrap_or(1.0),
            input.translate.map_or(glam::Vec3::ZERO, glam::Vec3::from),
        );
        compose::append(&mut cloud, other).with_context(|| name.clone())?;
    }
    Ok((cloud, estimate_s))
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

fn render(a: RenderArgs) -> Result<()> {
    if a.list_methods {
        for m in METHODS {
            println!("{}", m.name);
        }
        return Ok(());
    }
    let file = a.file.context("FILE is required")?;
    let config = MethodConfig::parse(&a.method)?;
    let (width, height) = parse_size(&a.size)?;
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
    let (cloud, estimate_s) = load_scene(
        &file,
        &settings,
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
    let (scene, info) = upload_for(&ctx, &cloud, coloring, config.method)?;
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

fn view(a: ViewArgs) -> Result<()> {
    let config = MethodConfig::parse(&a.method)?;
    let size = a.size.as_deref().map(parse_size).transpose()?;
    let settings = view_settings(&a.camera)?;
    let script = a
        .script
        .as_deref()
        .map(crate::app::script::Script::load)
        .transpose()?;
    crate::app::script::check_camera_file(&a.camera_file)?;
    if let Some(dir) = &a.screenshot_dir {
        if !dir.is_dir() {
            bail!("{}: the screenshot directory does not exist", dir.display());
        }
    }
    let (cloud, _) = load_scene(
        &a.file,
        &settings,
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
    crate::app::run(
        cloud,
        crate::app::ViewerOptions {
            title: format!("surfel - {}", a.file.display()),
            file: a.file.file_name().map_or_else(
                || a.file.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            ),
            method: config,
            camera: settings.camera(centre, radius, up),
            up,
            lights: settings.lights,
            size,
            post: settings.post,
            color_by,
            coloring,
            frames: a.frames,
            validation: a.validation || crate::gpu::context::validation_requested(),
            script,
            camera_file: a.camera_file,
            screenshot_dir: a.screenshot_dir,
            estimate,
        },
    )
}

fn info(a: InfoArgs) -> Result<()> {
    let cloud = load_prepared(&a.file, &a.input.options(false))?;
    println!("file              {}", a.file.display());
    println!("points            {}", cloud.len());
    println!("records in file   {}", cloud.stats.records);
    println!("dropped (NaN/inf) {}", cloud.stats.dropped_non_finite);
    println!("dropped (invalid) {}", cloud.stats.dropped_invalid);
    let duplicates = cloud.duplicates();
    println!(
        "duplicates        {} points at {} distinct positions",
        duplicates.points, duplicates.positions
    );
    if let Some(columns) = &cloud.stats.guessed_columns {
        println!("columns guessed   {columns} (from their count; name them with a first row or --columns)");
    }
    if let Some(levels) = &cloud.stats.levels {
        let per_level: Vec<String> = levels.points.iter().map(u64::to_string).collect();
        println!(
            "octree levels     read {} of {} (points per level: {}); {} points skipped",
            levels.read,
            levels.points.len(),
            per_level.join(", "),
            levels.points_skipped()
        );
    }
    println!(
        "faces             {}",
        cloud.faces.as_ref().map_or(0, |f| f.len())
    );
    let mut attrs = vec!["position"];
    attrs.extend(cloud.normals.as_ref().map(|_| "normal"));
    attrs.extend(cloud.colors.as_ref().map(|_| "color"));
    attrs.extend(cloud.radii.as_ref().map(|_| "radius"));
    let scalars: Vec<&str> = cloud.scalars.iter().map(|s| s.name.as_str()).collect();
    attrs.extend(scalars);
    println!("attributes        {}", attrs.join(", "));
    if !cloud.scalars.is_empty() {
        println!("scalar fields     min .. max (2nd .. 98th percentile)");
        for s in &cloud.scalars {
            let (min, max) = color::min_max(&s.values);
            let [lo, hi] = color::robust_range(&s.values);
            println!("  {:<22} {min} .. {max} ({lo} .. {hi})", s.name);
        }
    }
    let mut fields = color::fields(&cloud);
    let normals = match (&cloud.normals, &cloud.radii, a.input.k) {
        (Some(_), Some(_), _) => "from the file".to_owned(),
        (_, _, 0) => "none (--k 0)".to_owned(),
        _ => {
            if cloud.normals.is_none() {
                let at = fields
                    .iter()
                    .position(|f| f == "elevation")
                    .map_or(0, |i| i + 1);
                fields.insert(at, "normal".to_owned());
            }
            format!(
                "estimated (k = {}) for the methods that read them and for --color-by normal",
                a.input.k
            )
        }
    };
    println!("normals, radii    {normals}");
    println!("color by          {}", fields.join(", "));
    if let Some((lo, hi)) = cloud.bounds() {
        let o = cloud.origin;
        println!("origin            {:.3} {:.3} {:.3}", o.x, o.y, o.z);
        println!("bounds (local)    {lo:.6} .. {hi:.6}");
    }
    let (up, source) = match a.up {
        Some(up) => (up, "--up"),
        None => (cloud.up, "format default"),
    };
    println!("up axis           {} ({source})", up.name());
    let n = cloud.len() as u64;
    let streams = crate::streams::StreamLayout::streams_for(&cloud, None);
    let mut total = 0;
    println!("GPU streams       bytes/point  MiB");
    for s in streams {
        let bytes = crate::streams::StreamLayout::stream_bytes(s, n);
        total += bytes;
        println!(
            "  {:<22} {:>5}  {:>9.2}",
            s.name(),
            s.bytes_per_point(),
            bytes as f64 / (1 << 20) as f64
        );
    }
    if !cloud.scalars.is_empty() {
        println!(
            "  {:<22} {:>5}  (the field colored by, when one is)",
            "scalar f32", 4
        );
    }
    let batches = n.div_ceil(u64::from(crate::gpu::layout::BATCH_POINTS));
    println!(
        "GPU memory        {:.2} bytes/point, {:.2} MiB in {batches} batches of {} points",
        total as f64 / n.max(1) as f64,
        total as f64 / (1 << 20) as f64,
        crate::gpu::layout::BATCH_POINTS
    );
    if !a.no_device {
        let ctx = context(false)?;
        println!("{}", ctx.caps);
    }
    Ok(())
}

fn sample(a: SampleArgs) -> Result<()> {
    let mesh = crate::scene::load(&a.mesh)?;
    let cloud = crate::scene::sample::sample_mesh(&mesh, a.points, a.seed)
        .with_context(|| format!("{}: cannot sample", a.mesh.display()))?;
    crate::scene::ply::save(&a.out, &cloud)
        .with_context(|| format!("{}: cannot write", a.out.display()))?;
    eprintln!("{} points -> {}", cloud.len(), a.out.display());
    Ok(())
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
struct Found {
    visibility: crate::hpr::Visibility,
    /// How the points were found.
    note: String,
    /// The sector approximation's √k.
    sectors: Option<u32>,
}

/// How the sector approximation runs.
#[derive(Clone, Copy, Debug, Default)]
struct SectorOptions {
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
fn visible_points(
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
    let (scene, _) = crate::render::upload(&ctx, cloud)?;
    // Stream order is the Morton order of the positions.
    let order = crate::streams::morton_order(&cloud.positions);
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

fn hpr(a: HprArgs) -> Result<()> {
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
    let view = crate::eval::hpr_view::HprView::new(&cloud, eye, target, parse_size(&a.size)?);
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
    image::save_buffer(
        out,
        bytemuck::cast_slice(&frame.color),
        view.width,
        view.height,
        image::ColorType::Rgba8,
    )
    .with_context(|| format!("{}: cannot write", out.display()))
}

fn hpr_study(a: HprStudyArgs) -> Result<()> {
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
        size: parse_size(&a.size)?,
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

fn convert_lines(a: ConvertLinesArgs) -> Result<()> {
    use crate::lines;
    if crate::scene::format_extension(&a.mesh) != "obj" {
        bail!(
            "{}: expected an .obj mesh (polygons and materials)",
            a.mesh.display()
        );
    }
    let mesh = crate::scene::obj::load_polygons(&a.mesh)?;
    if mesh.polygons.is_empty() {
        bail!("{}: the mesh has no faces", a.mesh.display());
    }
    let model = lines::convert(&mesh);
    let s = &model.stats;
    println!("file              {}", a.mesh.display());
    println!("components        {}", s.components);
    println!(
        "faces             {} in: {} converted, {} kept",
        mesh.polygons.len(),
        s.faces_converted,
        s.faces_kept
    );
    for (name, k) in [("ribbons", s.ribbons), ("tubes", s.tubes)] {
        println!(
            "{name:<17} {} polylines, {} segments, {} vertices",
            k.polylines, k.segments, k.vertices
        );
    }
    println!(
        "triangles kept    {} triangles, {} vertices",
        s.triangles, s.triangle_vertices
    );
    println!(
        "vertices          {} in, {} out ({:.1} %)",
        s.input_vertices,
        s.output_vertices(),
        100.0 * s.output_vertices() as f64 / s.input_vertices.max(1) as f64
    );
    if mesh.uncolored > 0 {
        println!("no material       {} faces (grey)", mesh.uncolored);
    }
    if let Some(out) = &a.out {
        lines::save(out, &model).with_context(|| format!("{}: cannot write", out.display()))?;
        println!("written           {}", out.display());
    }
    Ok(())
}

fn bench(a: BenchArgs) -> Result<()> {
    use crate::eval::config::BenchConfig;
    let config = match &a.sweep {
        Some(path) => BenchConfig::load(path)?,
        None => BenchConfig::quick()?,
    };
    let ctx = context(a.validation)?;
    let out = crate::eval::bench::run(&ctx, &config, &a.out, true)?;
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    eprintln!(
        "{} records -> {}, {}, {} charts",
        out.results.records.len(),
        out.json.display(),
        out.csv.display(),
        out.charts.len()
    );
    if a.report {
        let path = crate::eval::report::write_report(&out.results, &out.json, &a.out)?;
        eprintln!("report -> {}", path.display());
    }
    Ok(())
}

fn report(a: ReportArgs) -> Result<()> {
    let results = crate::eval::results::Results::read_json(&a.results)?;
    let out = a.out.unwrap_or_else(|| {
        a.results
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default()
    });
    let path = crate::eval::report::write_report(&results, &a.results, &out)?;
    eprintln!("report -> {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Camera;
    use glam::Vec3;

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
        assert_eq!(none.camera(c, r, Up::Y), Camera::framing(c, r));
        assert_eq!(
            none.camera(c, r, Up::Z),
            Camera::orbit_about(Up::Z, c, r, 30.0, 35.0, 1.0)
        );
        let forced = view_settings(&camera_args(Some("default"), Some(Up::Y))).expect("settings");
        assert_eq!(forced.camera(c, r, Up::Z), Camera::framing(c, r));
        let orbit = view_settings(&camera_args(Some("0,84"), Some(Up::Z))).expect("settings");
        assert_eq!(
            orbit.camera(c, r, Up::Y),
            Camera::orbit_about(Up::Z, c, r, 0.0, 84.0, 1.0)
        );
    }
}

//! The benchmark sweep file (`surfel bench sweep.toml`) and its expansion into [`Job`]s.
//!
//! ```toml
//! resolutions = ["640x480", "1280x720"]   # "WxH"
//! lights = [1, 8]                         # light counts
//!
//! [frames]
//! warmup = 5                              # frames rendered before timing
//! measured = 20                           # frames timed (>= 1)
//! pipeline_stats = false                  # also count shader invocations per pass
//!
//! [[models]]
//! path = "data/bunny.obj"                 # relative to the sweep file's directory
//! name = "bunny"                          # optional, defaults to the file stem
//! points = [10000, 100000]                # optional: also resample the mesh to N points
//! truth = "plant.obj"                      # optional: score against this model's mesh
//! (top level) color = false                # optional: shade everything in the base color
//!
//! [[methods]]
//! name = "points"
//! params = { size = [1, 3] }              # lists, expanded as a cartesian product
//!
//! [[poses]]                               # optional, defaults to one "default" pose
//! name = "side"
//! orbit = [45.0, 20.0]                    # azimuth, elevation (degrees); or "default",
//! distance = 1.0                          # or eye = [x, y, z] with target = [x, y, z]
//!
//! [[poses]]
//! name = "flight"
//! path = "flight.toml"                    # a camera path (`scene::path`): timed along it
//!
//! [[stress]]
//! kind = "grazing"                        # see StressKind for kinds and units
//! values = [0, 45, 85]
//! ```
//!
//! Unknown keys are errors; every validation error names the offending key.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::scene::path::CameraPath;
use crate::scene::sample::{show_bytes, SAMPLED_POINT_BYTES};

/// Host memory a resampled point takes while its cloud is uploaded: the cloud
/// ([`SAMPLED_POINT_BYTES`]), the Morton sort's 8-byte keys, the stream order and its inverse
/// (4 bytes each) and a Phong method's linear normal field (8).
pub const SAMPLED_UPLOAD_BYTES: u64 = SAMPLED_POINT_BYTES + 8 + 4 + 4 + 8;

/// The sweep `surfel bench --quick` runs (`benches/sweeps/quick.toml`).
const QUICK_TOML: &str = include_str!("../../benches/sweeps/quick.toml");

/// A sweep file that failed to load or validate. Where an error has a `source()`, the message
/// leaves it out, so a report that prints the chain shows each cause once.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: cannot read the sweep file")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The text is not valid TOML for the schema.
    #[error("invalid sweep file: {0}")]
    Parse(toml::de::Error),
    /// A value is out of range or inconsistent; `key` is its path in the file.
    #[error("{key}: {message}")]
    Invalid { key: String, message: String },
    /// The sweep file `path` failed to parse or validate.
    #[error("{path}: {error}")]
    InFile {
        path: PathBuf,
        error: Box<ConfigError>,
    },
    /// The clouds a sweep resamples would not fit in the host memory available.
    #[error(
        "{origin}, {key}: {count} sampled points need {} of memory, {} is available (a sampled \
         point takes {SAMPLED_UPLOAD_BYTES} bytes while it is uploaded and \
         {SAMPLED_POINT_BYTES} after, and the sweep keeps every cloud it samples: {kept} points \
         before these)",
        show_bytes(*.needed),
        show_bytes(*.available)
    )]
    Memory {
        origin: SweepOrigin,
        key: String,
        count: u64,
        /// Points of the sweep's earlier resampled clouds, kept while these are made.
        kept: u64,
        needed: u64,
        available: u64,
    },
    /// A model file of the sweep cannot be read.
    #[error(
        "{origin}, {key}: {path}: cannot read the model (relative paths resolve against {})",
        .origin.base_dir().display()
    )]
    Model {
        origin: SweepOrigin,
        key: String,
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Where a sweep came from, which decides what its relative model paths are relative to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SweepOrigin {
    /// A sweep file: relative paths resolve against the file's directory.
    File(PathBuf),
    /// The built-in quick sweep: relative paths resolve against `dir`, the directory of
    /// `benches/sweeps/quick.toml` in the source tree the binary was built from (see
    /// [`quick_sweep_dir`]).
    Quick { dir: PathBuf },
    /// Sweep text given directly: relative paths resolve against the current directory.
    Text,
}

impl SweepOrigin {
    /// The directory relative model paths resolve against (empty: the current directory).
    pub fn base_dir(&self) -> &Path {
        match self {
            SweepOrigin::File(path) => path.parent().unwrap_or(Path::new("")),
            SweepOrigin::Quick { dir } => dir,
            SweepOrigin::Text => Path::new(""),
        }
    }
}

impl fmt::Display for SweepOrigin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SweepOrigin::File(path) => write!(f, "sweep file {}", path.display()),
            SweepOrigin::Quick { .. } => {
                f.write_str("built-in sweep --quick (benches/sweeps/quick.toml)")
            }
            SweepOrigin::Text => f.write_str("sweep text"),
        }
    }
}

/// The directory the `--quick` sweep's relative paths resolve against: `benches/sweeps` of the
/// source tree at build time (`CARGO_MANIFEST_DIR`), so the sweep runs from any directory; when
/// that tree no longer exists (a binary copied elsewhere), `benches/sweeps` under the current
/// directory, as when run from a checkout's root.
pub fn quick_sweep_dir() -> PathBuf {
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/sweeps");
    if built.is_dir() {
        built
    } else {
        PathBuf::from("benches/sweeps")
    }
}

fn invalid(key: impl Into<String>, message: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        key: key.into(),
        message: message.into(),
    }
}

/// The kinds of stress sweep. Values are in the units described per variant; the order of
/// increasing severity is [`StressKind::severity_increases_with_value`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StressKind {
    /// Camera-side: angle in degrees between the view direction and the surface normal,
    /// 0 (facing) to below 90 (grazing); typical 0..85.
    Grazing,
    /// Camera-side: screen-space pixels per point (zooming in until points are sparse),
    /// at least 1; typical 1..64.
    Magnification,
    /// Cloud-side: fraction of the points kept, in (0, 1]; typical 1.0..0.01
    /// ([`crate::eval::stress::subsample`]).
    Subsample,
    /// Cloud-side: positional noise sigma as a fraction of the bounding-box diagonal,
    /// at least 0; typical 0..0.02 ([`crate::eval::stress::noise`]).
    Noise,
    /// Cloud-side: density contrast between the densest and sparsest end of the cloud,
    /// at least 1 ([`crate::eval::stress::nonuniform`]).
    Nonuniform,
    /// Camera-side: camera distance from the bounding-sphere centre as a fraction of its
    /// radius, > 0; typical 3.0 (outside) .. 0.5 (inside the cloud).
    Inside,
}

impl StressKind {
    /// Every kind, in file order.
    pub const ALL: [StressKind; 6] = [
        StressKind::Grazing,
        StressKind::Magnification,
        StressKind::Subsample,
        StressKind::Noise,
        StressKind::Nonuniform,
        StressKind::Inside,
    ];

    /// The name used in sweep files and results.
    pub fn as_str(self) -> &'static str {
        match self {
            StressKind::Grazing => "grazing",
            StressKind::Magnification => "magnification",
            StressKind::Subsample => "subsample",
            StressKind::Noise => "noise",
            StressKind::Nonuniform => "nonuniform",
            StressKind::Inside => "inside",
        }
    }

    /// Axis label of the value, with its unit.
    pub fn unit(self) -> &'static str {
        match self {
            StressKind::Grazing => "angle to normal (deg)",
            StressKind::Magnification => "pixels per point",
            StressKind::Subsample => "fraction of points kept",
            StressKind::Noise => "noise sigma / bbox diagonal",
            StressKind::Nonuniform => "density contrast",
            StressKind::Inside => "camera distance / radius",
        }
    }

    /// True when larger values are harsher (false for `subsample` and `inside`, which get
    /// harsher as the value shrinks).
    pub fn severity_increases_with_value(self) -> bool {
        !matches!(self, StressKind::Subsample | StressKind::Inside)
    }

    /// Checks one value's range; the message says what is allowed.
    pub fn check_value(self, v: f64) -> Result<(), String> {
        let ok = v.is_finite()
            && match self {
                StressKind::Grazing => (0.0..90.0).contains(&v),
                StressKind::Magnification => v >= 1.0,
                StressKind::Subsample => v > 0.0 && v <= 1.0,
                StressKind::Noise => v >= 0.0,
                StressKind::Nonuniform => v >= 1.0,
                StressKind::Inside => v > 0.0,
            };
        let allowed = match self {
            StressKind::Grazing => "degrees in [0, 90)",
            StressKind::Magnification => "pixels per point >= 1",
            StressKind::Subsample => "a fraction in (0, 1]",
            StressKind::Noise => "a fraction of the bbox diagonal >= 0",
            StressKind::Nonuniform => "a density contrast >= 1",
            StressKind::Inside => "a fraction of the radius > 0",
        };
        if ok {
            Ok(())
        } else {
            Err(format!("{v} out of range for {self}: expected {allowed}"))
        }
    }
}

impl fmt::Display for StressKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for StressKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        StressKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<_> = StressKind::ALL.iter().map(|k| k.as_str()).collect();
                format!(
                    "unknown stress kind {s:?}{} (expected one of {})",
                    crate::suggest::did_you_mean(s, names.iter().copied()),
                    names.join(", ")
                )
            })
    }
}

/// A model to render.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSpec {
    /// Short name used in results (the file stem unless given).
    pub name: String,
    /// The model file, resolved against the sweep's [`SweepOrigin::base_dir`].
    pub path: PathBuf,
    /// Point counts to resample the mesh to for the time-vs-points sweep (may be empty).
    pub points: Vec<u64>,
    /// Another model whose mesh is the ground truth and whose bounding sphere frames the
    /// camera (a converted form of it, e.g. a plant as lines against the plant's triangles).
    pub truth: Option<PathBuf>,
}

/// A camera pose, relative to the model's bounding sphere unless `LookAt`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PoseSpec {
    /// The default framing (orbit 0, 0 at distance 1).
    Default,
    /// Azimuth/elevation in degrees around the bounding-sphere centre; `distance` scales the
    /// default framing distance.
    Orbit {
        azimuth: f32,
        elevation: f32,
        distance: f32,
    },
    /// Eye and target in scene coordinates.
    LookAt { eye: [f32; 3], target: [f32; 3] },
    /// A camera path (`scene::path`) read from `file`: the job times one frame per path frame
    /// along it and scores its first frame, the first key's pose.
    Path { file: PathBuf, path: CameraPath },
}

impl PoseSpec {
    /// The camera distance as a multiple of the default framing's (`None` for eye/target).
    pub fn distance(&self) -> Option<f64> {
        match self {
            PoseSpec::Default => Some(1.0),
            PoseSpec::Orbit { distance, .. } => Some(f64::from(*distance)),
            PoseSpec::LookAt { .. } | PoseSpec::Path { .. } => None,
        }
    }
}

/// A named pose.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedPose {
    pub name: String,
    pub pose: PoseSpec,
}

/// A method with lists of parameter values.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSpec {
    pub name: String,
    /// Parameter name to candidate values (TOML scalars rendered as strings).
    pub params: BTreeMap<String, Vec<String>>,
}

impl MethodSpec {
    /// The cartesian product of the parameter lists, in key order with the last key varying
    /// fastest; a method without parameters yields one empty map.
    pub fn combinations(&self) -> Vec<BTreeMap<String, String>> {
        let mut out = vec![BTreeMap::new()];
        for (key, values) in &self.params {
            out = out
                .into_iter()
                .flat_map(|combo| {
                    values.iter().map(move |v| {
                        let mut c = combo.clone();
                        c.insert(key.clone(), v.clone());
                        c
                    })
                })
                .collect();
        }
        out
    }
}

/// Frames rendered per job.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameCounts {
    /// Frames rendered and discarded before timing.
    pub warmup: u32,
    /// Frames timed (at least 1); medians and spreads are over these.
    pub measured: u32,
    /// Also count each pass's shader invocations (pipeline statistics queries, which may
    /// perturb the times beside them; the device needs `pipelineStatisticsQuery`).
    #[serde(default)]
    pub pipeline_stats: bool,
}

impl Default for FrameCounts {
    fn default() -> Self {
        FrameCounts {
            warmup: 5,
            measured: 20,
            pipeline_stats: false,
        }
    }
}

/// One stress sweep: a kind and the values to visit.
#[derive(Clone, Debug, PartialEq)]
pub struct StressSweep {
    pub kind: StressKind,
    pub values: Vec<f64>,
}

/// A validated sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchConfig {
    /// Where the sweep came from (for messages).
    pub origin: SweepOrigin,
    /// Model paths are resolved: relative paths in the sweep are joined to
    /// [`SweepOrigin::base_dir`].
    pub models: Vec<ModelSpec>,
    pub methods: Vec<MethodSpec>,
    /// `(width, height)` pairs, in file order.
    pub resolutions: Vec<(u32, u32)>,
    pub poses: Vec<NamedPose>,
    pub lights: Vec<u32>,
    pub frames: FrameCounts,
    pub stress: Vec<StressSweep>,
    /// Whether points are shaded in their colors (`color = false`: every method and the
    /// ground truth in the base color, to compare geometry across inputs whose colors differ).
    pub color: bool,
}

/// Which part of the sweep a job belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobGroup {
    /// Native model, every resolution x pose x light count.
    Baseline,
    /// Mesh resampled to `Job::points`.
    Points,
    /// A stress value applied.
    Stress,
}

/// One render-and-measure unit of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    pub group: JobGroup,
    pub model: ModelSpec,
    /// Resample the mesh to this many points (`Points` jobs only); `None` renders the model as
    /// loaded.
    pub points: Option<u64>,
    pub method: String,
    pub params: BTreeMap<String, String>,
    pub width: u32,
    pub height: u32,
    pub pose: NamedPose,
    pub lights: u32,
    /// The stress applied (`Stress` jobs only).
    pub stress: Option<(StressKind, f64)>,
    pub frames: FrameCounts,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    #[serde(default)]
    models: Vec<RawModel>,
    #[serde(default)]
    methods: Vec<RawMethod>,
    #[serde(default)]
    resolutions: Vec<String>,
    #[serde(default)]
    poses: Vec<RawPose>,
    #[serde(default)]
    lights: Option<Vec<u32>>,
    #[serde(default)]
    frames: Option<FrameCounts>,
    #[serde(default)]
    stress: Vec<RawStress>,
    color: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModel {
    path: PathBuf,
    name: Option<String>,
    #[serde(default)]
    points: Vec<u64>,
    truth: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMethod {
    name: String,
    #[serde(default)]
    params: BTreeMap<String, toml::Value>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum RawOrbit {
    Named(String),
    Angles(Vec<f32>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPose {
    name: String,
    orbit: Option<RawOrbit>,
    distance: Option<f32>,
    eye: Option<[f32; 3]>,
    target: Option<[f32; 3]>,
    path: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStress {
    kind: String,
    values: Vec<f64>,
}

fn scalar_string(key: &str, v: &toml::Value) -> Result<String, ConfigError> {
    match v {
        toml::Value::String(s) => Ok(s.clone()),
        toml::Value::Integer(i) => Ok(i.to_string()),
        toml::Value::Float(f) if f.is_finite() => Ok(f.to_string()),
        toml::Value::Boolean(b) => Ok(b.to_string()),
        other => Err(invalid(
            key,
            format!(
                "expected a string, number or boolean, got {}",
                other.type_str()
            ),
        )),
    }
}

fn finite_all(key: &str, values: &[f32]) -> Result<(), ConfigError> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(invalid(key, format!("{v} is not finite"))),
        None => Ok(()),
    }
}

fn convert_pose(i: usize, raw: RawPose, base: &Path) -> Result<NamedPose, ConfigError> {
    let key = |field: &str| format!("poses[{i}].{field}");
    if raw.name.trim().is_empty() {
        return Err(invalid(key("name"), "must not be empty"));
    }
    if let Some(file) = raw.path {
        if raw.orbit.is_some() || raw.eye.is_some() || raw.target.is_some() {
            return Err(invalid(
                key("path"),
                "cannot be combined with orbit or eye/target (the path's keys give the poses)",
            ));
        }
        if raw.distance.is_some() {
            return Err(invalid(key("distance"), "only applies to orbit poses"));
        }
        let file = base.join(file);
        let path = CameraPath::load(&file).map_err(|e| invalid(key("path"), format!("{e:#}")))?;
        return Ok(NamedPose {
            name: raw.name,
            pose: PoseSpec::Path { file, path },
        });
    }
    let pose = match (raw.orbit, raw.eye, raw.target) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            return Err(invalid(key("orbit"), "cannot be combined with eye/target"))
        }
        (None, Some(eye), Some(target)) => {
            if raw.distance.is_some() {
                return Err(invalid(key("distance"), "only applies to orbit poses"));
            }
            finite_all(&key("eye"), &eye)?;
            finite_all(&key("target"), &target)?;
            if eye == target {
                return Err(invalid(key("eye"), "must differ from target"));
            }
            PoseSpec::LookAt { eye, target }
        }
        (None, Some(_), None) => return Err(invalid(key("target"), "required with eye")),
        (None, None, Some(_)) => return Err(invalid(key("eye"), "required with target")),
        (orbit, None, None) => {
            let distance = raw.distance.unwrap_or(1.0);
            if !(distance.is_finite() && distance > 0.0) {
                return Err(invalid(key("distance"), format!("{distance} must be > 0")));
            }
            let angles = match orbit {
                None => [0.0, 0.0],
                Some(RawOrbit::Named(s)) if s == "default" => [0.0, 0.0],
                Some(RawOrbit::Named(s)) => {
                    let parts: Result<Vec<f32>, _> =
                        s.split(',').map(|t| t.trim().parse::<f32>()).collect();
                    match parts.ok().as_deref() {
                        Some(&[az, el]) => [az, el],
                        _ => {
                            return Err(invalid(
                                key("orbit"),
                                format!("expected \"default\", \"AZ,EL\" or [AZ, EL], got {s:?}"),
                            ))
                        }
                    }
                }
                Some(RawOrbit::Angles(v)) => match v.as_slice() {
                    &[az, el] => [az, el],
                    _ => return Err(invalid(key("orbit"), "expected [azimuth, elevation]")),
                },
            };
            finite_all(&key("orbit"), &angles)?;
            if angles == [0.0, 0.0] && distance == 1.0 {
                PoseSpec::Default
            } else {
                PoseSpec::Orbit {
                    azimuth: angles[0],
                    elevation: angles[1],
                    distance,
                }
            }
        }
    };
    Ok(NamedPose {
        name: raw.name,
        pose,
    })
}

impl BenchConfig {
    /// Reads and validates a sweep file; relative model paths resolve against its directory.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_from(&text, SweepOrigin::File(path.to_path_buf())).map_err(|e| {
            ConfigError::InFile {
                path: path.to_path_buf(),
                error: Box::new(e),
            }
        })
    }

    /// Parses and validates sweep TOML; relative model paths stay relative to the current
    /// directory.
    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        Self::parse_from(text, SweepOrigin::Text)
    }

    /// Parses and validates sweep TOML from `origin`, resolving relative model paths against
    /// [`SweepOrigin::base_dir`].
    pub fn parse_from(text: &str, origin: SweepOrigin) -> Result<Self, ConfigError> {
        let raw: RawConfig = toml::from_str(text).map_err(ConfigError::Parse)?;
        if raw.models.is_empty() {
            return Err(invalid("models", "at least one model is required"));
        }
        let mut models = Vec::new();
        for (i, m) in raw.models.into_iter().enumerate() {
            let name = match m.name {
                Some(n) if n.trim().is_empty() => {
                    return Err(invalid(format!("models[{i}].name"), "must not be empty"))
                }
                Some(n) => n,
                None => m
                    .path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .filter(|s| !s.is_empty())
                    .ok_or_else(|| invalid(format!("models[{i}].path"), "has no file name"))?,
            };
            if let Some(p) = m.points.iter().position(|&p| p == 0) {
                return Err(invalid(format!("models[{i}].points[{p}]"), "must be > 0"));
            }
            if models.iter().any(|other: &ModelSpec| other.name == name) {
                return Err(invalid(
                    format!("models[{i}].name"),
                    format!("duplicate model name {name:?}"),
                ));
            }
            models.push(ModelSpec {
                name,
                path: origin.base_dir().join(m.path),
                points: m.points,
                truth: m.truth.map(|t| origin.base_dir().join(t)),
            });
        }
        if raw.methods.is_empty() {
            return Err(invalid("methods", "at least one method is required"));
        }
        let mut methods = Vec::new();
        for (i, m) in raw.methods.into_iter().enumerate() {
            if m.name.trim().is_empty() {
                return Err(invalid(format!("methods[{i}].name"), "must not be empty"));
            }
            let mut params = BTreeMap::new();
            for (k, v) in m.params {
                let key = format!("methods[{i}].params.{k}");
                let values = match v {
                    toml::Value::Array(items) => items
                        .iter()
                        .enumerate()
                        .map(|(j, item)| scalar_string(&format!("{key}[{j}]"), item))
                        .collect::<Result<Vec<_>, _>>()?,
                    scalar => vec![scalar_string(&key, &scalar)?],
                };
                if values.is_empty() {
                    return Err(invalid(key, "empty list"));
                }
                params.insert(k, values);
            }
            methods.push(MethodSpec {
                name: m.name,
                params,
            });
        }
        if raw.resolutions.is_empty() {
            return Err(invalid("resolutions", "at least one \"WxH\" is required"));
        }
        let resolutions = raw
            .resolutions
            .iter()
            .enumerate()
            .map(|(i, r)| {
                crate::frame::Size::parse(r)
                    .map(crate::frame::Size::pair)
                    .map_err(|e| invalid(format!("resolutions[{i}]"), e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let poses = if raw.poses.is_empty() {
            vec![NamedPose {
                name: "default".into(),
                pose: PoseSpec::Default,
            }]
        } else {
            raw.poses
                .into_iter()
                .enumerate()
                .map(|(i, p)| convert_pose(i, p, origin.base_dir()))
                .collect::<Result<Vec<_>, _>>()?
        };
        for (i, pose) in poses.iter().enumerate() {
            if poses[..i].iter().any(|p| p.name == pose.name) {
                return Err(invalid(
                    format!("poses[{i}].name"),
                    format!("duplicate pose name {:?}", pose.name),
                ));
            }
        }
        let lights = raw.lights.unwrap_or_else(|| vec![1]);
        if lights.is_empty() {
            return Err(invalid("lights", "at least one light count is required"));
        }
        let frames = raw.frames.unwrap_or_default();
        if frames.measured == 0 {
            return Err(invalid("frames.measured", "must be at least 1"));
        }
        let mut stress = Vec::new();
        for (i, s) in raw.stress.into_iter().enumerate() {
            let kind: StressKind = s
                .kind
                .parse()
                .map_err(|e| invalid(format!("stress[{i}].kind"), e))?;
            if s.values.is_empty() {
                return Err(invalid(format!("stress[{i}].values"), "empty list"));
            }
            for (j, &v) in s.values.iter().enumerate() {
                kind.check_value(v)
                    .map_err(|e| invalid(format!("stress[{i}].values[{j}]"), e))?;
            }
            stress.push(StressSweep {
                kind,
                values: s.values,
            });
        }
        Ok(BenchConfig {
            origin,
            models,
            methods,
            resolutions,
            poses,
            lights,
            frames,
            stress,
            color: raw.color.unwrap_or(true),
        })
    }

    /// Checks that every model file can be read, so a missing file fails the sweep before any
    /// rendering; the error names the sweep, the model's key and the resolved path.
    pub fn check_models(&self) -> Result<(), ConfigError> {
        for (i, m) in self.models.iter().enumerate() {
            let files =
                std::iter::once(("path", &m.path)).chain(m.truth.iter().map(|t| ("truth", t)));
            for (key, path) in files {
                if let Err(source) = std::fs::File::open(path) {
                    return Err(ConfigError::Model {
                        origin: self.origin.clone(),
                        key: format!("models[{i}].{key}"),
                        path: path.clone(),
                        source,
                    });
                }
            }
        }
        Ok(())
    }

    /// Refuses a sweep whose resampled clouds (`points` of the models) would not fit in
    /// `available` bytes of host memory, before anything is loaded: the bench keeps every cloud
    /// it resamples ([`SAMPLED_POINT_BYTES`] a point) and needs [`SAMPLED_UPLOAD_BYTES`] a
    /// point of the one it uploads. The models as loaded are not counted. The error names the
    /// first count that does not fit.
    pub fn check_memory(&self, available: u64) -> Result<(), ConfigError> {
        let mut sampled = std::collections::BTreeSet::new();
        let mut kept = 0u64;
        for (i, m) in self.models.iter().enumerate() {
            for (j, &count) in m.points.iter().enumerate() {
                if !sampled.insert((&m.path, count)) {
                    continue;
                }
                let needed = kept
                    .saturating_mul(SAMPLED_POINT_BYTES)
                    .saturating_add(count.saturating_mul(SAMPLED_UPLOAD_BYTES));
                if needed > available {
                    return Err(ConfigError::Memory {
                        origin: self.origin.clone(),
                        key: format!("models[{i}].points[{j}]"),
                        count,
                        kept,
                        needed,
                        available,
                    });
                }
                kept = kept.saturating_add(count);
            }
        }
        Ok(())
    }

    /// The tiny sweep for CI (`benches/sweeps/quick.toml`, embedded at build time): the bunny
    /// and two resampled copies, `points` at two sizes and the `mesh` ground truth, 64x64 and
    /// 128x128, 1 warm-up and 3 measured frames, subsample, grazing and magnification stresses.
    /// Relative model paths resolve against [`quick_sweep_dir`].
    pub fn quick() -> Result<Self, ConfigError> {
        Self::parse_from(
            QUICK_TOML,
            SweepOrigin::Quick {
                dir: quick_sweep_dir(),
            },
        )
    }

    /// Expands the sweep into jobs, in this order:
    ///
    /// 1. `Baseline`: for each model, resolution, pose, light count, method and parameter
    ///    combination (see [`MethodSpec::combinations`]), nested in that order (the last
    ///    varies fastest), the model as loaded.
    /// 2. `Points`: for each model, each of its `points` counts, each resolution, each method
    ///    and combination, at the first pose and light count (time against points is wanted
    ///    per resolution; the resampled cloud is shared by a count's consecutive jobs).
    /// 3. `Stress`: for each model, each stress sweep in file order, each value in file
    ///    order, each method and combination, at the first resolution, pose and light count
    ///    with the model as loaded.
    pub fn jobs(&self) -> Vec<Job> {
        let mut jobs = Vec::new();
        let method_combos: Vec<(&str, BTreeMap<String, String>)> = self
            .methods
            .iter()
            .flat_map(|m| {
                m.combinations()
                    .into_iter()
                    .map(move |c| (m.name.as_str(), c))
            })
            .collect();
        let (Some(&first_res), Some(first_pose), Some(&first_lights)) = (
            self.resolutions.first(),
            self.poses.first(),
            self.lights.first(),
        ) else {
            return jobs;
        };
        let frames = self.frames;
        let job =
            |group, model: &ModelSpec, (width, height): (u32, u32), pose: &NamedPose, lights| {
                let jobs: Vec<Job> = method_combos
                    .iter()
                    .map(|(method, params)| Job {
                        group,
                        model: model.clone(),
                        points: None,
                        method: method.to_string(),
                        params: params.clone(),
                        width,
                        height,
                        pose: pose.clone(),
                        lights,
                        stress: None,
                        frames,
                    })
                    .collect();
                jobs
            };
        for model in &self.models {
            for &res in &self.resolutions {
                for pose in &self.poses {
                    for &lights in &self.lights {
                        jobs.extend(job(JobGroup::Baseline, model, res, pose, lights));
                    }
                }
            }
        }
        for model in &self.models {
            for &n in &model.points {
                for &res in &self.resolutions {
                    let group = job(JobGroup::Points, model, res, first_pose, first_lights);
                    jobs.extend(group.into_iter().map(|j| Job {
                        points: Some(n),
                        ..j
                    }));
                }
            }
        }
        for model in &self.models {
            for sweep in &self.stress {
                for &value in &sweep.values {
                    let group = job(JobGroup::Stress, model, first_res, first_pose, first_lights);
                    jobs.extend(group.into_iter().map(|j| Job {
                        stress: Some((sweep.kind, value)),
                        ..j
                    }));
                }
            }
        }
        jobs
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = r#"
resolutions = ["64x64", "128x96"]
lights = [1, 4]

[frames]
warmup = 2
measured = 5

[[models]]
path = "data/bunny.obj"
points = [1000, 5000]

[[models]]
path = "data/x.ply"
name = "dragon"

[[methods]]
name = "points"
params = { size = [1, 2, 3], round = [true, false] }

[[methods]]
name = "mesh"

[[poses]]
name = "front"

[[poses]]
name = "side"
orbit = "45,20"

[[poses]]
name = "inside"
eye = [0, 0, 0.5]
target = [0, 0, -1]

[[stress]]
kind = "grazing"
values = [0, 45, 85]

[[stress]]
kind = "subsample"
values = [1.0, 0.1]
"#;

    fn err(text: &str) -> String {
        BenchConfig::parse(text).unwrap_err().to_string()
    }

    #[test]
    fn parses_the_sample() {
        let c = BenchConfig::parse(SAMPLE).unwrap();
        assert_eq!(c.models[0].name, "bunny");
        assert_eq!(c.models[1].name, "dragon");
        assert_eq!(c.resolutions, vec![(64, 64), (128, 96)]);
        assert_eq!(
            c.frames,
            FrameCounts {
                warmup: 2,
                measured: 5,
                pipeline_stats: false,
            }
        );
        assert_eq!(c.poses[0].pose, PoseSpec::Default);
        assert_eq!(
            c.poses[1].pose,
            PoseSpec::Orbit {
                azimuth: 45.0,
                elevation: 20.0,
                distance: 1.0
            }
        );
        assert!(matches!(c.poses[2].pose, PoseSpec::LookAt { .. }));
        assert_eq!(c.methods[0].params["round"], vec!["true", "false"]);
        assert_eq!(c.stress[1].kind, StressKind::Subsample);
    }

    #[test]
    fn expansion_counts_and_order() {
        let c = BenchConfig::parse(SAMPLE).unwrap();
        let jobs = c.jobs();
        let combos = 3 * 2 + 1;
        let baseline = 2 * 2 * 3 * 2 * combos;
        let points = 2 * 2 * combos;
        let stress = 2 * (3 + 2) * combos;
        assert_eq!(jobs.len(), baseline + points + stress);
        let count = |g| jobs.iter().filter(|j| j.group == g).count();
        assert_eq!(count(JobGroup::Baseline), baseline);
        assert_eq!(count(JobGroup::Points), points);
        assert_eq!(count(JobGroup::Stress), stress);
        // Keys in sorted order, values in file order, last key fastest:
        // round=true,size=1 then round=true,size=2 ...
        assert_eq!(jobs[0].params["round"], "true");
        assert_eq!(jobs[0].params["size"], "1");
        assert_eq!(jobs[1].params["size"], "2");
        assert_eq!(jobs[3].params["round"], "false");
        assert_eq!(jobs[6].method, "mesh");
        assert!(jobs[6].params.is_empty());
        assert_eq!(jobs[7].lights, 4);
        assert_eq!(jobs[baseline].points, Some(1000));
        assert_eq!((jobs[baseline].width, jobs[baseline].height), (64, 64));
        let s = &jobs[baseline + points];
        assert_eq!(s.stress, Some((StressKind::Grazing, 0.0)));
        assert_eq!(s.model.name, "bunny");
        assert_eq!(s.frames.measured, 5);
        // Deterministic.
        assert_eq!(jobs, c.jobs());
    }

    #[test]
    fn validation_errors_name_the_key() {
        let base = "resolutions = [\"8x8\"]\n[[models]]\npath = \"a.obj\"\n[[methods]]\nname = \"points\"\n";
        assert!(BenchConfig::parse(base).is_ok());
        let cases = [
            ("resolutions = [\"8x8\"]\n[[methods]]\nname = \"p\"\n", "models:"),
            (
                "resolutions = [\"8by8\"]\n[[models]]\npath = \"a.obj\"\n[[methods]]\nname = \"p\"\n",
                "resolutions[0]:",
            ),
            (&format!("{base}params = {{ size = [] }}\n"), "methods[0].params.size: empty list"),
            (&format!("{base}params = {{ size = [[1]] }}\n"), "methods[0].params.size[0]:"),
            (&format!("{base}[frames]\nwarmup = 0\nmeasured = 0\n"), "frames.measured:"),
            (&format!("{base}[[stress]]\nkind = \"wobble\"\nvalues = [1]\n"), "stress[0].kind:"),
            (
                &format!("{base}[[stress]]\nkind = \"subsample\"\nvalues = [1.0, 1.5]\n"),
                "stress[0].values[1]:",
            ),
            (&format!("{base}[[stress]]\nkind = \"grazing\"\nvalues = [90]\n"), "stress[0].values[0]:"),
            (&format!("{base}[[poses]]\nname = \"p\"\norbit = [1]\n"), "poses[0].orbit:"),
            (&format!("{base}[[poses]]\nname = \"p\"\neye = [1, 2, 3]\n"), "poses[0].target:"),
            (
                &format!("{base}[[poses]]\nname = \"p\"\norbit = \"1,2\"\neye = [1, 2, 3]\n"),
                "poses[0].orbit:",
            ),
            (&format!("{base}[[poses]]\nname = \"p\"\ndistance = 0\n"), "poses[0].distance:"),
            (
                &format!("{base}[[poses]]\nname = \"p\"\npath = \"f.toml\"\norbit = [1, 2]\n"),
                "poses[0].path: cannot be combined with orbit",
            ),
            (
                &format!("{base}[[poses]]\nname = \"p\"\npath = \"no/such/path.toml\"\n"),
                "poses[0].path: no/such/path.toml: cannot read camera path",
            ),
            (&format!("{base}lightz = [1]\n"), "unknown field `lightz`"),
        ];
        for (text, expected) in cases {
            let e = err(text);
            assert!(e.contains(expected), "{expected:?} not in {e:?}");
        }
        let dup = format!("{base}[[poses]]\nname = \"p\"\n[[poses]]\nname = \"p\"\n");
        assert!(err(&dup).contains("poses[1].name: duplicate pose name"));
        let dup = base.replace("[[methods]]", "[[models]]\npath = \"b/a.ply\"\n[[methods]]");
        assert!(err(&dup).contains("models[1].name: duplicate model name \"a\""));
        let e = err("resolutions = [\"8x8\"]\n[[models]]\npath = \"a.obj\"\npoints = [0]\n[[methods]]\nname = \"p\"\n");
        assert!(e.contains("models[0].points[0]"), "{e}");
    }

    #[test]
    fn a_path_pose_reads_its_camera_path_beside_the_sweep() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/sweeps");
        let config = BenchConfig::load(&dir.join("path.toml")).unwrap();
        let flight = &config.poses[1];
        let PoseSpec::Path { file, path } = &flight.pose else {
            panic!("{flight:?}");
        };
        assert_eq!(file, &dir.join("../paths/orbit-zoom.toml"));
        assert_eq!(path.frames, 60);
        assert_eq!(path.keys.len(), 3);
        assert_eq!(flight.pose.distance(), None);
        let bad = dir.join("../../target/surfel-bad-path-sweep.toml");
        std::fs::write(
            &bad,
            "resolutions = [\"8x8\"]\n[[models]]\npath = \"a.ply\"\n[[methods]]\nname = \"points\"\n\
             [[poses]]\nname = \"p\"\npath = \"../benches/sweeps/path.toml\"\n",
        )
        .unwrap();
        let e = format!("{:#}", BenchConfig::load(&bad).unwrap_err());
        std::fs::remove_file(&bad).ok();
        assert!(
            e.contains("poses[0].path:") && e.contains("invalid camera path"),
            "{e}"
        );
    }

    #[test]
    fn quick_config_and_example_files_are_valid() {
        let q = BenchConfig::quick().unwrap();
        let jobs = q.jobs();
        // Baseline: 2 resolutions x 4 method configurations; 2 point counts x 2 resolutions
        // x 4; 3 stress kinds x 2 values x 4.
        assert_eq!(jobs.len(), 2 * 4 + 2 * 2 * 4 + 3 * 2 * 4);
        assert!(jobs
            .iter()
            .all(|j| j.frames.measured == 3 && j.width <= 128));
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/sweeps");
        let quick = BenchConfig::load(&dir.join("quick.toml")).unwrap();
        assert_eq!(quick.models, q.models);
        assert_eq!(quick.jobs(), jobs);
        // Both resolve against the file's directory, wherever the process runs.
        assert!(q.models[0].path.starts_with(&dir), "{:?}", q.models[0].path);
        q.check_models().unwrap();
        for name in [
            "lavapipe.toml",
            "full.toml",
            "compute.toml",
            "splat.toml",
            "splat-lights.toml",
            "splat-stress.toml",
            "splat-grazing.toml",
            "pyramid.toml",
            "pyramid-stress.toml",
            "plants.toml",
            "kernel.toml",
            "hpr.toml",
            "lod.toml",
            "path.toml",
        ] {
            BenchConfig::load(&dir.join(name))
                .unwrap()
                .check_models()
                .unwrap();
        }
        let full = BenchConfig::load(&dir.join("full.toml")).unwrap();
        let kinds: Vec<_> = full.stress.iter().map(|s| s.kind).collect();
        assert_eq!(kinds, StressKind::ALL.to_vec());
        assert!(full.jobs().len() > jobs.len());
    }

    #[test]
    fn relative_model_paths_resolve_against_the_sweep_file() {
        let text = "resolutions = [\"8x8\"]\n[[models]]\npath = \"../data/a.ply\"\n\
                    [[models]]\npath = \"/abs/b.ply\"\n[[methods]]\nname = \"points\"\n";
        let origin = SweepOrigin::File(PathBuf::from("sweeps/s.toml"));
        let c = BenchConfig::parse_from(text, origin.clone()).unwrap();
        assert_eq!(c.models[0].path, Path::new("sweeps/../data/a.ply"));
        assert_eq!(c.models[1].path, Path::new("/abs/b.ply"));
        let e = c.check_models().unwrap_err().to_string();
        assert_eq!(
            e,
            "sweep file sweeps/s.toml, models[0].path: sweeps/../data/a.ply: cannot read the \
             model (relative paths resolve against sweeps)"
        );
        let text_only = BenchConfig::parse(text).unwrap();
        assert_eq!(text_only.models[0].path, Path::new("../data/a.ply"));
    }

    #[test]
    fn resampled_clouds_beyond_the_memory_are_refused_naming_the_count() {
        let c = BenchConfig::parse_from(
            "resolutions = [\"8x8\"]\n[[methods]]\nname = \"points\"\n\
             [[models]]\npath = \"a.obj\"\npoints = [1000, 100000000]\n\
             [[models]]\npath = \"b.obj\"\npoints = [200000000, 1000000000]\n",
            SweepOrigin::File(PathBuf::from("big.toml")),
        )
        .unwrap();
        let gib = 1u64 << 30;
        // The last count: 300,001,000 points kept at 32 bytes and 10^9 uploaded at 56.
        assert_eq!(SAMPLED_UPLOAD_BYTES, 56);
        let e = c.check_memory(16 * gib).unwrap_err().to_string();
        assert_eq!(
            e,
            "sweep file big.toml, models[1].points[1]: 1000000000 sampled points need 61.1 GiB \
             of memory, 16.0 GiB is available (a sampled point takes 56 bytes while it is \
             uploaded and 32 after, and the sweep keeps every cloud it samples: 300001000 \
             points before these)"
        );
        let e = c.check_memory(8 * gib).unwrap_err().to_string();
        assert!(
            e.starts_with("sweep file big.toml, models[1].points[0]: 200000000 sampled points"),
            "{e}"
        );
        assert!(c.check_memory(62 * gib).is_ok());
    }

    #[test]
    fn stress_kinds_round_trip_and_order_severity() {
        for k in StressKind::ALL {
            assert_eq!(k.as_str().parse::<StressKind>().unwrap(), k);
        }
        assert!(StressKind::Grazing.severity_increases_with_value());
        assert!(!StressKind::Inside.severity_increases_with_value());
        assert!(StressKind::Magnification.check_value(0.5).is_err());
        assert!(StressKind::Noise.check_value(f64::NAN).is_err());
        let expected =
            "(expected one of grazing, magnification, subsample, noise, nonuniform, inside)";
        assert_eq!(
            "grazng".parse::<StressKind>().unwrap_err(),
            format!("unknown stress kind \"grazng\"; did you mean 'grazing'? {expected}")
        );
        assert_eq!(
            "wobble".parse::<StressKind>().unwrap_err(),
            format!("unknown stress kind \"wobble\" {expected}")
        );
    }
}

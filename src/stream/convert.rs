//! `surfel convert`: any input the loaders read, written as a COPC file by the `copc-writer`
//! crate (octree build, LAZ chunk compression, hierarchy pages).
//!
//! The input is loaded by the ordinary loader (with its checks), then fed to the writer as LAS
//! 1.4 records, in a pseudo-random order (see [`shuffled`]: the writer's coarse levels are the
//! first points it meets per octant): the writer spills them to a temporary file in the output's folder and
//! builds the octree from that spill, so its own memory stays bounded whatever the cloud's
//! size; the loaded cloud is what bounds conversion memory (about 30 bytes per point).
//!
//! Kept: positions (f64: the cloud's origin plus its f32 offsets), colour (8-bit values stored
//! as 16-bit, times 257), intensity, classification, returns, point source id, GPS time, and
//! as extra bytes (LAS 1.4 R15 §2.6, f32 each) the normals (`NormalX/Y/Z`), the splat radii
//! (`radius`) and every other scalar field. Coordinates are quantized at the finest decimal scale
//! that keeps the cloud's largest extent within 2^30 steps, so they keep their f32 precision.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use copc_core::{CancelCheck, LasPointRecord, StreamingLayout};
use copc_writer::{CopcWriteMetadata, CopcWriterParams};

use crate::scene::progress::Progress;
use crate::scene::{Cloud, ReadOptions};

/// Points per COPC node the writer aims for (the value PDAL and Untwine use).
pub const DEFAULT_NODE_POINTS: u32 = 100_000;

/// Conversions of at least this many points show a progress bar (on a terminal).
const PROGRESS_MIN_POINTS: usize = 1_000_000;

/// The names of the standard LAS fields among a cloud's scalars (as the loaders name them).
const STANDARD: [&str; 6] = [
    "intensity",
    "classification",
    "return_number",
    "number_of_returns",
    "point_source_id",
    "gps_time",
];

/// Extra-bytes names of the normal's components (the names PDAL writes).
pub const NORMAL_NAMES: [&str; 3] = ["NormalX", "NormalY", "NormalZ"];

/// Extra-bytes name of the splat radius.
pub const RADIUS_NAME: &str = "radius";

/// How [`convert`] writes.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// Target points per octree node.
    pub node_points: u32,
    /// How the input is read.
    pub read: ReadOptions,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        Self {
            node_points: DEFAULT_NODE_POINTS,
            read: ReadOptions::default(),
        }
    }
}

/// What a conversion did.
#[derive(Clone, Debug)]
pub struct ConvertStats {
    pub points: u64,
    /// Seconds loading the input.
    pub load_seconds: f64,
    /// Seconds building and writing the COPC file.
    pub write_seconds: f64,
    /// Bytes of the output.
    pub bytes: u64,
}

/// One f32 extra-bytes field: its name and where its values come from.
enum Extra<'a> {
    Normal(usize),
    Radius,
    Scalar(&'a str, &'a [f32]),
}

impl Extra<'_> {
    fn name(&self) -> &str {
        match self {
            Extra::Normal(axis) => NORMAL_NAMES[*axis],
            Extra::Radius => RADIUS_NAME,
            Extra::Scalar(name, _) => name,
        }
    }
}

/// The 192-byte extra-bytes descriptor of an f32 field named `name` (LAS 1.4 R15 table 24:
/// data type 9, no options; the name is at most 32 bytes).
fn descriptor(name: &str) -> [u8; 192] {
    let mut d = [0u8; 192];
    d[2] = 9;
    let bytes = name.as_bytes();
    let n = bytes.len().min(31);
    d[4..4 + n].copy_from_slice(&bytes[..n]);
    d
}

/// The smallest power of ten at least `extent / 2^30`, so coordinates measured from the
/// lower corner fit 30 bits (1e-9 for an empty or degenerate extent).
pub fn decimal_scale(extent: f64) -> f64 {
    let raw = extent / f64::from(1u32 << 30);
    if raw.is_finite() && raw > 0.0 {
        10f64.powf(raw.log10().ceil())
    } else {
        1e-9
    }
}

/// A fixed pseudo-random permutation of `0..n`. The writer fills a parent node with the first
/// points of each child octant in the order it is given them, so in file order (scan lines,
/// sorted tiles) a coarse level would cover only part of its cube; in a random order it is a
/// uniform random subsample of it.
fn shuffled(n: usize) -> Vec<u32> {
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut rng = crate::rng::SplitMix64::new(0x5eed_c0bc);
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}

/// Never cancels; the writer polls it.
struct Continue;

impl CancelCheck for Continue {
    fn check(&self) -> copc_core::Result<()> {
        Ok(())
    }
}

/// Converts `input` (any format [`crate::scene::load_with`] reads) into the COPC file `out`.
pub fn convert(input: &Path, out: &Path, options: &ConvertOptions) -> Result<ConvertStats> {
    if !out
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.to_ascii_lowercase().ends_with(".copc.laz"))
    {
        bail!(
            "{}: a COPC output's name ends in .copc.laz (readers choose the format by it)",
            out.display()
        );
    }
    if options.node_points < 1000 {
        bail!(
            "{} points per node: at least 1000 (a node is one LAZ chunk; smaller ones cost more in headers than they hold)",
            options.node_points
        );
    }
    let start = Instant::now();
    let cloud = crate::scene::load_with(input, &options.read)?;
    if cloud.is_empty() {
        bail!("{}: no points to convert", input.display());
    }
    let load_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    write(&cloud, out)?;
    let bytes = std::fs::metadata(out)
        .with_context(|| format!("{}: cannot read the written file", out.display()))?
        .len();
    Ok(ConvertStats {
        points: cloud.len() as u64,
        load_seconds,
        write_seconds: start.elapsed().as_secs_f64(),
        bytes,
    })
}

/// The folder the writer spills into: the output's (so the spill is on the output's disk).
fn spill_dir(out: &Path) -> PathBuf {
    match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Writes `cloud` as the COPC file `out`.
pub fn write(cloud: &Cloud, out: &Path) -> Result<()> {
    write_with(cloud, out, DEFAULT_NODE_POINTS)
}

/// [`write`] with `node_points` points per node.
pub fn write_with(cloud: &Cloud, out: &Path, node_points: u32) -> Result<()> {
    let scalar = |name: &str| {
        cloud
            .scalars
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.values.as_slice())
    };
    let mut extras = Vec::new();
    if cloud.normals.is_some() {
        extras.extend((0..3).map(Extra::Normal));
    }
    if cloud.radii.is_some() {
        extras.push(Extra::Radius);
    }
    extras.extend(
        cloud
            .scalars
            .iter()
            .filter(|s| !STANDARD.contains(&s.name.as_str()))
            .map(|s| Extra::Scalar(&s.name, &s.values)),
    );
    let descriptors: Vec<u8> = extras.iter().flat_map(|e| descriptor(e.name())).collect();
    let extra_bytes = u16::try_from(4 * extras.len())
        .ok()
        .filter(|&b| b < u16::MAX - 64)
        .with_context(|| format!("{} extra fields: too many for a LAS record", extras.len()))?;
    let has_color = cloud.colors.is_some();
    let layout = StreamingLayout {
        point_format: if has_color { 7 } else { 6 },
        has_gps: true,
        has_color,
        has_nir: false,
        has_waveform: false,
        extra_bytes,
        extra_bytes_descriptors: if extras.is_empty() {
            Vec::new()
        } else {
            vec![las::Vlr {
                user_id: "LASF_Spec".into(),
                record_id: 4,
                description: "surfel extra fields".into(),
                data: descriptors,
            }]
        },
    };
    let extent = cloud
        .bounds()
        .map_or(0.0, |(lo, hi)| f64::from((hi - lo).max_element()));
    let scale = decimal_scale(extent);
    let mut metadata = CopcWriteMetadata::default();
    metadata.scale = Some((scale, scale, scale));
    metadata.generating_software = Some(format!("surfel {}", env!("CARGO_PKG_VERSION")));
    let standard: Vec<Option<&[f32]>> = STANDARD.iter().map(|n| scalar(n)).collect();
    let progress = Progress::new(
        "converting",
        cloud.len(),
        cloud.len() >= PROGRESS_MIN_POINTS,
    );
    let order = shuffled(cloud.len());
    let records = order.iter().enumerate().map(|(done, &i)| {
        let i = i as usize;
        if done % 65536 == 0 {
            progress.advance(65536.min(cloud.len() - done));
        }
        let p = cloud.origin + cloud.positions[i].as_dvec3();
        let value = |k: usize| standard[k].map_or(0.0, |v| v[i]);
        let byte = |k: usize| value(k).clamp(0.0, 255.0) as u8;
        let [r, g, b, _] = cloud.colors.as_ref().map_or([0; 4], |c| c[i]);
        let mut extra = Vec::with_capacity(usize::from(extra_bytes));
        for e in &extras {
            let v = match e {
                Extra::Normal(axis) => cloud.normals.as_ref().map_or(0.0, |n| n[i][*axis]),
                Extra::Radius => cloud.radii.as_ref().map_or(0.0, |r| r[i]),
                Extra::Scalar(_, values) => values[i],
            };
            extra.extend_from_slice(&v.to_le_bytes());
        }
        Ok(LasPointRecord {
            x: p.x,
            y: p.y,
            z: p.z,
            intensity: value(0).clamp(0.0, 65535.0) as u16,
            classification: byte(1),
            return_number: byte(2).min(15),
            number_of_returns: byte(3).min(15),
            point_source_id: value(4).clamp(0.0, 65535.0) as u16,
            gps_time: f64::from(value(5)),
            red: u16::from(r) * 257,
            green: u16::from(g) * 257,
            blue: u16::from(b) * 257,
            extra_bytes: extra,
            ..LasPointRecord::default()
        })
    });
    let result = copc_writer::write_streaming_with_cancel(
        out,
        layout,
        records,
        &CopcWriterParams::new(node_points),
        &metadata,
        &spill_dir(out),
        &Continue,
    );
    progress.finish();
    result.map_err(|e| anyhow::anyhow!("{}: cannot write COPC: {e}", out.display()))
}

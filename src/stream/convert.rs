//! `surfel convert`: any input the loaders read, written as a COPC file by the `copc-writer`
//! crate (octree build, LAZ chunk compression, hierarchy pages).
//!
//! Points reach the writer as LAS 1.4 records in a pseudo-random order (the writer's coarse
//! levels are the first points it meets per octant, see [`shuffled`]); the writer spills them to
//! a temporary file beside the output and builds the octree from that spill, its own memory
//! bounded whatever the cloud's size. A binary PLY (what `surfel sample` writes), LAS and LAZ are
//! streamed in blocks through an external shuffle ([`Shuffler`]: random buckets on disk, each shuffled in
//! memory), so conversion memory stays bounded too; other formats are loaded whole by their
//! loader (with its checks), about 30 bytes per point.
//!
//! Kept: positions (f64: the cloud's origin plus its f32 offsets), colour (8-bit values stored
//! as 16-bit, times 257), intensity, classification, returns, point source id, GPS time, and
//! as extra bytes (LAS 1.4 R15 §2.6, f32 each) the normals (`NormalX/Y/Z`), the splat radii
//! (`radius`) and every other scalar field. Coordinates are quantized at the finest decimal scale
//! that keeps the cloud's largest extent within 2^30 steps, so they keep their f32 precision.
//! NIR and waveforms (LAS point formats 4, 5, 8, 9, 10), which the writer cannot store, are
//! dropped with a warning ([`ConvertStats::warnings`]).
//!
//! A conversion whose [`ConvertOptions::stop`] flag is set (by the command line's SIGINT and
//! SIGTERM handler) ends with an error; like a failed one, it leaves no temporary file (shuffle
//! buckets, the writer's spill and unfinished output) behind. The output gets the mode a new
//! file gets (0666 less the umask), not the writer's private 0600.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::DVec3;

use anyhow::{bail, Context as _, Result};
use copc_core::{CancelCheck, LasPointRecord, StreamingLayout};
use copc_writer::{CopcWriteMetadata, CopcWriterParams};

use crate::rng::SplitMix64;
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
    /// Stops the conversion when set (from a signal handler: a store is all it does).
    pub stop: Option<&'static AtomicBool>,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        Self {
            node_points: DEFAULT_NODE_POINTS,
            read: ReadOptions::default(),
            stop: None,
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
    /// What the output lacks that the input has, each naming the input.
    pub warnings: Vec<String>,
}

/// What a cloud's records carry beyond positions, colours and the standard fields: the f32
/// extra-bytes fields, in order (decided from the whole cloud, or a streamed input's first
/// chunk).
#[derive(Clone, Debug, PartialEq)]
struct Fields {
    colors: bool,
    normals: bool,
    radii: bool,
    /// Scalar fields that are not standard LAS fields.
    scalars: Vec<String>,
}

/// One cloud's columns in the order of [`Fields`].
struct View<'a> {
    cloud: &'a Cloud,
    /// Multiplies intensities (65,535 for a cloud whose intensities are fractions of 1).
    intensity_scale: f32,
    standard: [Option<&'a [f32]>; 6],
    scalars: Vec<&'a [f32]>,
    extra_bytes: usize,
}

impl Fields {
    fn of(cloud: &Cloud) -> Self {
        Self {
            colors: cloud.colors.is_some(),
            normals: cloud.normals.is_some(),
            radii: cloud.radii.is_some(),
            scalars: cloud
                .scalars
                .iter()
                .filter(|s| !STANDARD.contains(&s.name.as_str()))
                .map(|s| s.name.clone())
                .collect(),
        }
    }

    fn names(&self) -> Vec<&str> {
        let mut names = Vec::new();
        if self.normals {
            names.extend(NORMAL_NAMES);
        }
        if self.radii {
            names.push(RADIUS_NAME);
        }
        names.extend(self.scalars.iter().map(String::as_str));
        names
    }

    /// The writer's record layout: point format 7 with colours, else 6, and one f32 extra
    /// field per name.
    fn layout(&self) -> Result<StreamingLayout> {
        let names = self.names();
        let extra_bytes = u16::try_from(4 * names.len())
            .ok()
            .filter(|&b| b < u16::MAX - 64)
            .with_context(|| format!("{} extra fields: too many for a LAS record", names.len()))?;
        Ok(StreamingLayout {
            point_format: if self.colors { 7 } else { 6 },
            has_gps: true,
            has_color: self.colors,
            has_nir: false,
            has_waveform: false,
            extra_bytes,
            extra_bytes_descriptors: if names.is_empty() {
                Vec::new()
            } else {
                vec![las::Vlr {
                    user_id: "LASF_Spec".into(),
                    record_id: 4,
                    description: "surfel extra fields".into(),
                    data: names.iter().flat_map(|n| descriptor(n)).collect(),
                }]
            },
        })
    }

    /// `cloud`'s columns; fails when it lacks one of the fields (a streamed chunk unlike the
    /// first).
    fn view<'a>(&self, cloud: &'a Cloud, intensity_scale: f32) -> Result<View<'a>> {
        let scalar = |name: &str| {
            cloud
                .scalars
                .iter()
                .find(|s| s.name == name)
                .map(|s| s.values.as_slice())
        };
        if Self::of(cloud) != *self {
            bail!("a block of points with other fields than the first block's");
        }
        Ok(View {
            cloud,
            intensity_scale,
            standard: STANDARD.map(scalar),
            scalars: self
                .scalars
                .iter()
                .map(|n| scalar(n).expect("checked"))
                .collect(),
            extra_bytes: 4 * self.names().len(),
        })
    }
}

impl View<'_> {
    /// The LAS record of point `i`.
    fn record(&self, i: usize) -> LasPointRecord {
        let cloud = self.cloud;
        let p = cloud.origin + cloud.positions[i].as_dvec3();
        let value = |k: usize| self.standard[k].map_or(0.0, |v| v[i]);
        let byte = |k: usize| value(k).clamp(0.0, 255.0) as u8;
        let [r, g, b, _] = cloud.colors.as_ref().map_or([0; 4], |c| c[i]);
        let mut extra = Vec::with_capacity(self.extra_bytes);
        if let Some(n) = &cloud.normals {
            for v in n[i].to_array() {
                extra.extend_from_slice(&v.to_le_bytes());
            }
        }
        if let Some(radii) = &cloud.radii {
            extra.extend_from_slice(&radii[i].to_le_bytes());
        }
        for values in &self.scalars {
            extra.extend_from_slice(&values[i].to_le_bytes());
        }
        LasPointRecord {
            x: p.x,
            y: p.y,
            z: p.z,
            intensity: (value(0) * self.intensity_scale).clamp(0.0, 65535.0) as u16,
            classification: byte(1),
            return_number: byte(2).min(15),
            number_of_returns: byte(3).min(15),
            point_source_id: value(4).clamp(0.0, 65535.0) as u16,
            gps_time: f64::from(value(5)) + cloud.stats.gps_time_origin.unwrap_or(0.0),
            red: u16::from(r) * 257,
            green: u16::from(g) * 257,
            blue: u16::from(b) * 257,
            extra_bytes: extra,
            ..LasPointRecord::default()
        }
    }
}

/// The factor taking `cloud`'s intensities to LAS's 16 bits: 65,535 when they are fractions
/// within 0..1 (E57 and normalised text files), else 1 (already counts).
fn intensity_scale(cloud: &Cloud) -> f32 {
    let Some(values) = cloud
        .scalars
        .iter()
        .find(|s| s.name == "intensity")
        .map(|s| &s.values)
    else {
        return 1.0;
    };
    let fractions =
        values.iter().all(|v| (0.0..=1.0).contains(v)) && values.iter().any(|v| v.fract() != 0.0);
    if fractions {
        65535.0
    } else {
        1.0
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

/// A conversion's stop flag ([`ConvertOptions::stop`]); the writer polls it, and so does
/// every record pushed into a [`Shuffler`].
#[derive(Clone, Copy, Debug, Default)]
struct Stop(Option<&'static AtomicBool>);

impl Stop {
    fn requested(self) -> bool {
        self.0.is_some_and(|flag| flag.load(Ordering::Relaxed))
    }
}

impl CancelCheck for Stop {
    fn check(&self) -> copc_core::Result<()> {
        if self.requested() {
            Err(copc_core::Error::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// Converts `input` (any format [`crate::scene::load_with`] reads) into the COPC file `out`.
/// A binary PLY is streamed in blocks (memory bounded whatever its size); other formats are
/// loaded whole. A stopped conversion fails with "interrupted"; a stopped or failed one leaves
/// neither temporary files nor an output.
pub fn convert(input: &Path, out: &Path, options: &ConvertOptions) -> Result<ConvertStats> {
    let stop = Stop(options.stop);
    let result = convert_until(input, out, options, stop);
    if stop.requested() {
        bail!(
            "{}: interrupted; the temporary files are removed and no output is written",
            out.display()
        );
    }
    let stats = result?;
    set_new_file_mode(out)?;
    Ok(stats)
}

/// Converts every file of `inputs` into the one COPC file `out` (one input: [`convert`]).
pub fn convert_many(
    inputs: &[PathBuf],
    out: &Path,
    options: &ConvertOptions,
) -> Result<ConvertStats> {
    match inputs {
        [] => bail!("no input files to convert"),
        [input] => convert(input, out, options),
        _ => bail!(
            "merging {} inputs into one COPC file is not supported",
            inputs.len()
        ),
    }
}

/// Gives `out` the mode a newly created file gets, 0666 less the umask (the writer renames its
/// private temporary file, mode 0600, into place).
fn set_new_file_mode(out: &Path) -> Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // SAFETY: `umask` only swaps the process's file-creation mask; the old one is put back
        // at once.
        let mask = unsafe {
            let mask = libc::umask(0o022);
            libc::umask(mask);
            mask
        };
        std::fs::set_permissions(out, std::fs::Permissions::from_mode(0o666 & !mask))
            .with_context(|| format!("{}: cannot set the mode", out.display()))?;
    }
    Ok(())
}

/// [`convert`] until `stop` is requested.
fn convert_until(
    input: &Path,
    out: &Path,
    options: &ConvertOptions,
    stop: Stop,
) -> Result<ConvertStats> {
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
    crate::scene::check_regular(input)?;
    let start = Instant::now();
    let extension = crate::scene::format_extension(input);
    if extension == "ply" && !crate::lines::is_line_model(input) {
        if let Some(stats) = convert_streamed(input, out, options.node_points, start, stop)? {
            return Ok(stats);
        }
    }
    if extension == "e57" {
        return convert_e57(input, out, options.node_points, start, stop);
    }
    if matches!(extension.as_str(), "las" | "laz" | "copc.laz") {
        if let Some(stats) = convert_las(input, out, options.node_points, start, stop)? {
            return Ok(stats);
        }
    }
    let cloud = crate::scene::load_with(input, &options.read)?;
    if cloud.is_empty() {
        bail!("{}: no points to convert", input.display());
    }
    let load_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    write_until(&cloud, out, options.node_points, stop)?;
    Ok(ConvertStats {
        points: cloud.len() as u64,
        load_seconds,
        write_seconds: start.elapsed().as_secs_f64(),
        bytes: output_bytes(out)?,
        warnings: Vec::new(),
    })
}

fn output_bytes(out: &Path) -> Result<u64> {
    Ok(std::fs::metadata(out)
        .with_context(|| format!("{}: cannot read the written file", out.display()))?
        .len())
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
    write_until(cloud, out, node_points, Stop::default())
}

/// [`write_with`] until `stop` is requested.
fn write_until(cloud: &Cloud, out: &Path, node_points: u32, stop: Stop) -> Result<()> {
    let fields = Fields::of(cloud);
    let view = fields.view(cloud, intensity_scale(cloud))?;
    let extent = cloud
        .bounds()
        .map_or(0.0, |(lo, hi)| f64::from((hi - lo).max_element()));
    let progress = Progress::new(
        "converting",
        cloud.len(),
        cloud.len() >= PROGRESS_MIN_POINTS,
    );
    let order = shuffled(cloud.len());
    let records = order.iter().enumerate().map(|(done, &i)| {
        if done % 65536 == 0 {
            progress.advance(65536.min(cloud.len() - done));
        }
        Ok(view.record(i as usize))
    });
    let scale = decimal_scale(extent);
    let result = write_scaled(
        out,
        fields.layout()?,
        records,
        (scale, scale, scale),
        node_points,
        stop,
    );
    progress.finish();
    result
}

/// Hands `records` to the writer, coordinates quantized at `scale`.
fn write_scaled(
    out: &Path,
    layout: StreamingLayout,
    records: impl Iterator<Item = copc_core::Result<LasPointRecord>>,
    (sx, sy, sz): (f64, f64, f64),
    node_points: u32,
    stop: Stop,
) -> Result<()> {
    let mut metadata = CopcWriteMetadata::default();
    metadata.scale = Some((sx, sy, sz));
    metadata.generating_software = Some(format!("surfel {}", env!("CARGO_PKG_VERSION")));
    copc_writer::write_streaming_with_cancel(
        out,
        layout,
        records,
        &CopcWriterParams::new(node_points),
        &metadata,
        &spill_dir(out),
        &stop,
    )
    .map_err(|e| anyhow::anyhow!("{}: cannot write COPC: {e}", out.display()))
}

/// Points per shuffle bucket at most (what one bucket holds in memory when it is shuffled).
const BUCKET_POINTS: usize = 1 << 20;

/// An external shuffle: records go to one of `n` temporary files chosen at random, then each
/// file is read back, shuffled in memory and handed on, so the first records handed on are a
/// uniform sample of the whole input (see [`shuffled`]) with one bucket in memory at a time.
struct Shuffler {
    paths: Vec<PathBuf>,
    files: Vec<BufWriter<File>>,
    counts: Vec<usize>,
    layout: StreamingLayout,
    buf: Vec<u8>,
    rng: SplitMix64,
    stop: Stop,
}

impl Shuffler {
    fn new(dir: &Path, points: usize, layout: StreamingLayout, stop: Stop) -> Result<Self> {
        let n = points.div_ceil(BUCKET_POINTS).clamp(1, 4096);
        let mut paths = Vec::with_capacity(n);
        let mut files = Vec::with_capacity(n);
        for k in 0..n {
            let path = dir.join(format!(".surfel-convert-{}-{k}.part", std::process::id()));
            let file = File::create(&path)
                .with_context(|| format!("{}: cannot create a shuffle file", path.display()))?;
            paths.push(path);
            files.push(BufWriter::with_capacity(1 << 16, file));
        }
        Ok(Self {
            paths,
            files,
            counts: vec![0; n],
            buf: vec![0; layout.record_width()],
            layout,
            rng: SplitMix64::new(0x5eed_c0bc),
            stop,
        })
    }

    fn push(&mut self, record: &LasPointRecord) -> Result<()> {
        if self.stop.requested() {
            bail!("interrupted");
        }
        let k = (self.rng.next_u64() % self.files.len() as u64) as usize;
        copc_core::serialize_le(record, &self.layout, &mut self.buf)?;
        self.files[k]
            .write_all(&self.buf)
            .with_context(|| format!("{}: cannot write", self.paths[k].display()))?;
        self.counts[k] += 1;
        Ok(())
    }

    fn finish(mut self) -> Result<Shuffled> {
        for (file, path) in self.files.iter_mut().zip(&self.paths) {
            file.flush()
                .with_context(|| format!("{}: cannot write", path.display()))?;
        }
        Ok(Shuffled {
            paths: std::mem::take(&mut self.paths),
            counts: std::mem::take(&mut self.counts),
            layout: self.layout.clone(),
            next: 0,
            current: Vec::new(),
            rng: SplitMix64::new(0x5eed_b0c1),
        })
    }
}

impl Drop for Shuffler {
    fn drop(&mut self) {
        for path in &self.paths {
            // Best effort: a file that cannot be removed stays behind as `.surfel-convert-*`.
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The records of a [`Shuffler`], bucket after bucket, each shuffled.
struct Shuffled {
    paths: Vec<PathBuf>,
    counts: Vec<usize>,
    layout: StreamingLayout,
    next: usize,
    current: Vec<LasPointRecord>,
    rng: SplitMix64,
}

impl Shuffled {
    fn load(&mut self, k: usize) -> copc_core::Result<()> {
        let bytes = std::fs::read(&self.paths[k])
            .map_err(|e| copc_core::Error::io("read a shuffle bucket", e))?;
        let width = self.layout.record_width();
        if bytes.len() != self.counts[k] * width {
            return Err(copc_core::Error::InvalidData(format!(
                "{}: {} bytes, {} records of {width} expected",
                self.paths[k].display(),
                bytes.len(),
                self.counts[k]
            )));
        }
        let _ = std::fs::remove_file(&self.paths[k]);
        self.current = bytes
            .chunks_exact(width)
            .map(|r| copc_core::deserialize_le(r, &self.layout))
            .collect::<std::io::Result<_>>()
            .map_err(|e| copc_core::Error::io("decode a shuffle bucket", e))?;
        for i in (1..self.current.len()).rev() {
            let j = (self.rng.next_u64() % (i as u64 + 1)) as usize;
            self.current.swap(i, j);
        }
        Ok(())
    }
}

impl Iterator for Shuffled {
    type Item = copc_core::Result<LasPointRecord>;

    fn next(&mut self) -> Option<Self::Item> {
        while self.current.is_empty() {
            if self.next == self.paths.len() {
                return None;
            }
            self.next += 1;
            if let Err(e) = self.load(self.next - 1) {
                return Some(Err(e));
            }
        }
        self.current.pop().map(Ok)
    }
}

impl Drop for Shuffled {
    fn drop(&mut self) {
        for path in &self.paths[self.next..] {
            // Best effort, as for `Shuffler`.
            let _ = std::fs::remove_file(path);
        }
    }
}

/// Streams a binary PLY into the writer through a [`Shuffler`]; `None` when the file cannot
/// be streamed.
fn convert_streamed(
    input: &Path,
    out: &Path,
    node_points: u32,
    start: Instant,
    stop: Stop,
) -> Result<Option<ConvertStats>> {
    let mut fields: Option<Fields> = None;
    let mut scale: Option<f32> = None;
    let mut shuffler: Option<Shuffler> = None;
    let mut failed: Option<anyhow::Error> = None;
    let mut points = 0usize;
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let dir = spill_dir(out);
    let streamed = crate::scene::ply::for_each_chunk(input, 32 << 20, |total, mut chunk| {
        if failed.is_some() {
            return;
        }
        chunk.retain_finite();
        let result = (|| -> Result<()> {
            let fields = fields.get_or_insert_with(|| Fields::of(&chunk));
            if shuffler.is_none() {
                shuffler = Some(Shuffler::new(&dir, total, fields.layout()?, stop)?);
            }
            let shuffler = shuffler.as_mut().expect("created above");
            let scale = *scale.get_or_insert_with(|| intensity_scale(&chunk));
            let view = fields.view(&chunk, scale)?;
            for i in 0..chunk.len() {
                let r = view.record(i);
                let p = DVec3::new(r.x, r.y, r.z);
                (lo, hi) = (lo.min(p), hi.max(p));
                shuffler.push(&r)?;
            }
            points += chunk.len();
            Ok(())
        })();
        if let Err(e) = result {
            failed = Some(e);
        }
    })?;
    if streamed.is_none() {
        return Ok(None);
    }
    if let Some(e) = failed {
        return Err(e.context(format!("{}: cannot convert", input.display())));
    }
    let (Some(fields), Some(shuffler)) = (fields, shuffler) else {
        bail!("{}: no points to convert", input.display());
    };
    if points == 0 {
        bail!("{}: no points to convert", input.display());
    }
    let scale = decimal_scale((hi - lo).max_element());
    write_shuffled(
        out,
        shuffler,
        fields.layout()?,
        points,
        (scale, scale, scale),
        node_points,
        start,
    )
    .map(Some)
}

/// Streams a LAS or LAZ file's records (every LAS field as it is, extra bytes included; NIR and
/// waveform data, which the writer cannot keep, dropped with a warning) into the writer
/// through a [`Shuffler`], at the input's scale; `None` for a file only the loader reads.
fn convert_las(
    input: &Path,
    out: &Path,
    node_points: u32,
    start: Instant,
    stop: Stop,
) -> Result<Option<ConvertStats>> {
    let file = input.display().to_string();
    let dir = spill_dir(out);
    // The `las` crate's reader stays on the deep-stack thread (the LAZ decoder recurses).
    let opened = crate::scene::guard::deep_stack(|| -> Result<Option<_>> {
        let Some(mut reader) = crate::scene::las::open_blocks(input)? else {
            return Ok(None);
        };
        let header = reader.header().clone();
        let mut layout = StreamingLayout::from_las_header(&header);
        layout.has_nir = false;
        layout.has_waveform = false;
        let declared = usize::try_from(header.number_of_points()).unwrap_or(usize::MAX);
        let mut shuffler = Shuffler::new(&dir, declared, layout.clone(), stop)?;
        let mut data = las::PointDataBuilder::new().for_header(&header).build();
        let mut points = 0usize;
        loop {
            let n = crate::scene::guard::third_party(|| reader.fill_points(65_536, &mut data))
                .map_err(|e| anyhow::anyhow!("{file}: point record {points}: {e}"))?
                .map_err(|e| anyhow::anyhow!("{file}: point record {points}: {e}"))?;
            if n == 0 {
                return Ok(Some((header, layout, shuffler, points)));
            }
            for point in data.points() {
                let point =
                    point.map_err(|e| anyhow::anyhow!("{file}: point record {points}: {e}"))?;
                let mut record = LasPointRecord::from_las_point(&point);
                record.nir = 0;
                shuffler.push(&record)?;
                points += 1;
            }
        }
    })?;
    let Some((header, layout, shuffler, read)) = opened else {
        return Ok(None);
    };
    if read == 0 {
        bail!("{file}: no points to convert");
    }
    let t = header.transforms();
    let mut stats = write_shuffled(
        out,
        shuffler,
        layout,
        read,
        (t.x.scale, t.y.scale, t.z.scale),
        node_points,
        start,
    )?;
    let format = header.point_format();
    for (dropped, what) in [
        (format.has_nir, "NIR (near infrared)"),
        (format.has_waveform, "waveform data"),
    ] {
        if dropped {
            stats.warnings.push(format!(
                "{file}: point format {} has {what}, which a COPC file (point format 6 or 7) cannot hold; dropped",
                format.to_u8().unwrap_or_default()
            ));
        }
    }
    Ok(Some(stats))
}

/// Streams an E57 file's points (every scan, in the file's frame; colour and intensity when
/// scans record them) into the writer through a [`Shuffler`]. A first pass finds whether the
/// intensities are fractions of 1 (then scaled to 16 bits, as [`intensity_scale`] does).
fn convert_e57(
    input: &Path,
    out: &Path,
    node_points: u32,
    start: Instant,
    stop: Stop,
) -> Result<ConvertStats> {
    use crate::scene::e57::{for_each_point, E57Point};
    let (mut fractions, mut any_fraction) = (true, false);
    let (mut declared, mut colors) = (0u64, false);
    for_each_point(
        input,
        &mut |records, color, _| {
            (declared, colors) = (records, color);
            Ok(())
        },
        &mut |p: E57Point| {
            if let Some(v) = p.intensity {
                fractions &= (0.0..=1.0).contains(&v);
                any_fraction |= v.fract() != 0.0;
            }
            Ok(())
        },
    )?;
    let scale = if fractions && any_fraction {
        65535.0
    } else {
        1.0
    };
    let layout = Fields {
        colors,
        normals: false,
        radii: false,
        scalars: Vec::new(),
    }
    .layout()?;
    let n = usize::try_from(declared).unwrap_or(usize::MAX);
    let mut shuffler = Shuffler::new(&spill_dir(out), n, layout.clone(), stop)?;
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let mut points = 0usize;
    let file = input.display().to_string();
    for_each_point(input, &mut |_, _, _| Ok(()), &mut |p: E57Point| {
        if !p.world.is_finite() {
            return Ok(());
        }
        (lo, hi) = (lo.min(p.world), hi.max(p.world));
        let [r, g, b, _] = p.color.unwrap_or([0; 4]);
        let record = LasPointRecord {
            x: p.world.x,
            y: p.world.y,
            z: p.world.z,
            intensity: (p.intensity.unwrap_or(0.0) * scale).clamp(0.0, 65535.0) as u16,
            red: u16::from(r) * 257,
            green: u16::from(g) * 257,
            blue: u16::from(b) * 257,
            ..LasPointRecord::default()
        };
        shuffler
            .push(&record)
            .map_err(|e| crate::scene::LoadError::whole(&file, e.to_string()))?;
        points += 1;
        Ok(())
    })?;
    if points == 0 {
        bail!("{}: no points to convert", input.display());
    }
    let scale = decimal_scale((hi - lo).max_element());
    write_shuffled(
        out,
        shuffler,
        layout,
        points,
        (scale, scale, scale),
        node_points,
        start,
    )
}

/// Hands the `points` records of `shuffler` to the writer with a progress bar; `start` is when
/// reading the input began (the load time is measured up to now).
fn write_shuffled(
    out: &Path,
    shuffler: Shuffler,
    layout: StreamingLayout,
    points: usize,
    scale: (f64, f64, f64),
    node_points: u32,
    start: Instant,
) -> Result<ConvertStats> {
    let load_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let progress = Progress::new("converting", points, points >= PROGRESS_MIN_POINTS);
    let stop = shuffler.stop;
    let records = shuffler.finish()?.enumerate().map(|(done, r)| {
        if done % 65536 == 0 {
            progress.advance(65536.min(points - done));
        }
        r
    });
    let result = write_scaled(out, layout, records, scale, node_points, stop);
    progress.finish();
    result?;
    Ok(ConvertStats {
        points: points as u64,
        load_seconds,
        write_seconds: start.elapsed().as_secs_f64(),
        bytes: output_bytes(out)?,
        warnings: Vec::new(),
    })
}

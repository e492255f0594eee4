//! `surfel convert`: inputs written as one COPC file by [`super::copc_write`].
//!
//! LAS, LAZ and COPC inputs are read as raw records and re-encoded as point format 6 or 7
//! ([`super::records::Source`]): several of them merge into one file, read in parallel, each
//! into its own part of one buffer. Every other format is loaded whole by its loader (with its
//! checks) and its columns encoded ([`super::records::encode_cloud`]: normals in two 16-bit
//! octahedral coordinates, radii in 16 bits with a scale and offset).
//!
//! Merging follows one rule: the output has colours if any input has (black for the others),
//! the inputs' scale and offset when they all share them (else the finest scale of any input
//! and the lowest corner of all), their extra bytes when they all describe the same ones (else
//! none, with a warning), and their CRS, which must be the same for all (else an error naming
//! two files that differ). NIR and waveforms (point formats 4, 5, 8, 9, 10), which a COPC file
//! cannot hold, are dropped with a warning ([`ConvertStats::warnings`]).
//!
//! A conversion whose [`ConvertOptions::stop`] flag is set (by the command line's SIGINT and
//! SIGTERM handler) ends with an error; like a failed one, it leaves no partial output behind.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use glam::DVec3;
use rayon::prelude::*;

use super::copc_write::{self, Layout};
use super::records::{self, Source};
use crate::scene::{Cloud, ReadOptions};

/// Points per COPC node the writer aims for (the value PDAL and Untwine use).
pub const DEFAULT_NODE_POINTS: u32 = 100_000;

/// Points per block read from a LAS or LAZ file.
const BLOCK_POINTS: u64 = 65_536;

/// How [`convert`] writes.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// Target points per octree node.
    pub node_points: u32,
    /// How inputs other than LAS, LAZ and COPC are read.
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
    /// Octree nodes written.
    pub nodes: usize,
    /// Seconds reading the inputs.
    pub load_seconds: f64,
    /// Seconds building and writing the COPC file.
    pub write_seconds: f64,
    /// Of [`Self::write_seconds`], those sorting the points and building the octree.
    pub build_seconds: f64,
    /// Bytes of the output.
    pub bytes: u64,
    /// What the output lacks that an input has, each naming the input.
    pub warnings: Vec<String>,
}

impl ConvertOptions {
    fn stopped(&self) -> bool {
        self.stop.is_some_and(|flag| flag.load(Ordering::Relaxed))
    }
}

/// Converts `input` (any format [`crate::scene::load_with`] reads) into the COPC file `out`.
pub fn convert(input: &Path, out: &Path, options: &ConvertOptions) -> Result<ConvertStats> {
    convert_many(&[input.to_path_buf()], out, options)
}

/// Converts every file of `inputs` into the one COPC file `out`: any number of LAS, LAZ and
/// COPC files (merged by the rule in the module's notes), or one file of another format. A
/// stopped conversion fails with "interrupted"; a stopped or failed one leaves no output.
pub fn convert_many(
    inputs: &[PathBuf],
    out: &Path,
    options: &ConvertOptions,
) -> Result<ConvertStats> {
    let result = convert_until(inputs, out, options);
    if options.stopped() {
        bail!(
            "{}: interrupted; the temporary files are removed and no output is written",
            out.display()
        );
    }
    result
}

fn convert_until(inputs: &[PathBuf], out: &Path, options: &ConvertOptions) -> Result<ConvertStats> {
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
    if inputs.is_empty() {
        bail!("no input files to convert");
    }
    for input in inputs {
        crate::scene::check_regular(input)?;
    }
    let start = Instant::now();
    let las_family = inputs.iter().all(|i| {
        matches!(
            crate::scene::format_extension(i).as_str(),
            "las" | "laz" | "copc.laz"
        )
    });
    let (layout, records, warnings) = if las_family {
        match read_las(inputs, options)? {
            Some(read) => read,
            None => load_one(inputs, options)?,
        }
    } else {
        load_one(inputs, options)?
    };
    let points = records.len() / layout.record_len();
    if points == 0 {
        bail!("{}: no points to convert", inputs[0].display());
    }
    let load_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let written = copc_write::write(out, &layout, &records, options.node_points, &|| {
        options.stopped()
    })?;
    Ok(ConvertStats {
        points: points as u64,
        nodes: written.nodes,
        load_seconds,
        write_seconds: start.elapsed().as_secs_f64(),
        build_seconds: written.build_seconds,
        bytes: written.bytes,
        warnings,
    })
}

type Read = (Layout, Vec<u8>, Vec<String>);

/// The one input of another format than LAS, loaded whole by its loader and encoded.
fn load_one(inputs: &[PathBuf], options: &ConvertOptions) -> Result<Read> {
    let [input] = inputs else {
        bail!(
            "{}: only LAS, LAZ and COPC files merge into one COPC file; convert this one on its own",
            inputs
                .iter()
                .find(|i| {
                    !matches!(
                        crate::scene::format_extension(i).as_str(),
                        "las" | "laz" | "copc.laz"
                    )
                })
                .unwrap_or(&inputs[0])
                .display()
        );
    };
    let cloud = crate::scene::load_with(input, &options.read)?;
    if cloud.is_empty() {
        bail!("{}: no points to convert", input.display());
    }
    let (layout, records) = records::encode_cloud(&cloud)?;
    Ok((layout, records, Vec::new()))
}

/// One LAS input's header, as the merge needs it.
struct Input {
    path: PathBuf,
    header: las::Header,
    source: Source,
    points: u64,
}

impl Input {
    fn descriptors(&self) -> Vec<u8> {
        self.header
            .vlrs()
            .iter()
            .chain(self.header.evlrs())
            .filter(|v| v.user_id.trim_end_matches('\0') == "LASF_Spec" && v.record_id == 4)
            .flat_map(|v| v.data.clone())
            .collect()
    }
}

/// The output layout of `inputs` by the merge rule, with the warnings it gives.
fn merged_layout(inputs: &[Input]) -> Result<(Layout, Vec<String>)> {
    let mut warnings = Vec::new();
    let first = &inputs[0];
    let crs = |i: &Input| crate::scene::las::crs(i.header.vlrs().iter().chain(i.header.evlrs()));
    for other in &inputs[1..] {
        let (a, b) = (crs(first), crs(other));
        if a != b {
            bail!(
                "{} and {} have different coordinate reference systems ({} and {}); convert them to tiles (--tiles) or reproject one",
                first.path.display(),
                other.path.display(),
                a.as_deref().unwrap_or("none"),
                b.as_deref().unwrap_or("none")
            );
        }
    }
    let same_grid = inputs
        .iter()
        .all(|i| i.source.scale == first.source.scale && i.source.offset == first.source.offset);
    let (scale, offset) = if same_grid {
        (first.source.scale, first.source.offset)
    } else {
        let scale = inputs
            .iter()
            .fold(DVec3::splat(f64::INFINITY), |s, i| s.min(i.source.scale));
        let lo = inputs.iter().fold(DVec3::splat(f64::INFINITY), |lo, i| {
            let b = i.header.bounds();
            lo.min(DVec3::new(b.min.x, b.min.y, b.min.z))
        });
        (scale, (lo / scale).floor() * scale)
    };
    let extra = first.header.point_format().extra_bytes;
    let descriptors = first.descriptors();
    let keep_extra = inputs
        .iter()
        .all(|i| i.header.point_format().extra_bytes == extra && i.descriptors() == descriptors);
    if !keep_extra {
        warnings.push(format!(
            "{}: the inputs describe different extra bytes; the merged file keeps none",
            inputs
                .iter()
                .find(|i| i.descriptors() != descriptors
                    || i.header.point_format().extra_bytes != extra)
                .unwrap_or(first)
                .path
                .display()
        ));
    }
    for input in inputs {
        let format = input.header.point_format();
        for (dropped, what) in [
            (format.has_nir, "NIR (near infrared)"),
            (format.has_waveform, "waveform data"),
        ] {
            if dropped {
                warnings.push(format!(
                    "{}: point format {} has {what}, which a COPC file (point format 6 or 7) cannot hold; dropped",
                    input.path.display(),
                    input.source.format
                ));
            }
        }
    }
    let descriptors = if keep_extra && extra > 0 {
        descriptors
            .chunks_exact(192)
            .map(|d| d.try_into().expect("192 bytes"))
            .collect()
    } else {
        Vec::new()
    };
    let layout = Layout {
        format: if inputs.iter().any(|i| i.header.point_format().has_color) {
            7
        } else {
            6
        },
        extra_bytes: if keep_extra { extra } else { 0 },
        descriptors,
        scale,
        offset,
        vlrs: records::crs_vlrs(first.header.vlrs().iter().chain(first.header.evlrs())),
        standard_gps_time: inputs
            .iter()
            .all(|i| i.header.gps_time_type() == las::GpsTimeType::Standard),
    };
    Ok((layout, warnings))
}

/// Reads LAS, LAZ and COPC `inputs` into one buffer of records, in parallel; `None` when one of
/// them is a point-wise compressed LAZ (LASzip 1.2), which only the loader reads (and then
/// converts alone).
fn read_las(inputs: &[PathBuf], options: &ConvertOptions) -> Result<Option<Read>> {
    let mut opened = Vec::with_capacity(inputs.len());
    for path in inputs {
        let Some(reader) = crate::scene::las::open_blocks(path)? else {
            if inputs.len() == 1 {
                return Ok(None);
            }
            bail!(
                "{}: a point-wise compressed LAZ (LASzip 1.2) does not merge; convert it on its own",
                path.display()
            );
        };
        let header = reader.header().clone();
        let format = header.point_format();
        let t = header.transforms();
        let source = Source {
            format: format.to_u8().unwrap_or_default() & 0x3f,
            len: usize::from(format.len()),
            scale: DVec3::new(t.x.scale, t.y.scale, t.z.scale),
            offset: DVec3::new(t.x.offset, t.y.offset, t.z.offset),
            keep_extra: true,
        };
        opened.push(Input {
            path: path.clone(),
            points: header.number_of_points(),
            header,
            source,
        });
    }
    let (layout, warnings) = merged_layout(&opened)?;
    let len = layout.record_len();
    let total: u64 = opened.iter().map(|i| i.points).sum();
    let bytes = usize::try_from(total)
        .ok()
        .and_then(|n| n.checked_mul(len))
        .context("the inputs declare more points than this machine can address")?;
    // The records, their sort keys (16 bytes a point) and the nodes' indices (4).
    let needed = bytes as u64 + total * 20;
    if let Some(available) = crate::scene::sample::available_memory() {
        if needed > available {
            bail!(
                "{} points need about {:.1} GB to convert into one file and {:.1} GB are available; convert them as tiles (--tiles)",
                total,
                needed as f64 / 1e9,
                available as f64 / 1e9
            );
        }
    }
    let mut records = vec![0u8; bytes];
    let mut parts = Vec::with_capacity(opened.len());
    let mut rest = records.as_mut_slice();
    for input in opened {
        let (part, tail) = rest.split_at_mut(input.points as usize * len);
        rest = tail;
        parts.push((input, part));
    }
    parts
        .into_par_iter()
        .map(|(input, part)| read_into(&input, &layout, part, options))
        .collect::<Result<Vec<()>>>()?;
    Ok(Some((layout, records, warnings)))
}

/// Reads every record of `input` into `part` (its declared count of `layout`'s records):
/// an uncompressed file by positioned reads of blocks in parallel, a compressed one block
/// after block by the `las` crate.
fn read_into(
    input: &Input,
    layout: &Layout,
    part: &mut [u8],
    options: &ConvertOptions,
) -> Result<()> {
    let source = Source {
        keep_extra: layout.extra_bytes > 0,
        ..input.source
    };
    if input.header.point_format().is_compressed {
        read_compressed(input, source, layout, part, options)
    } else {
        read_uncompressed(input, source, layout, part, options)
    }
}

fn read_uncompressed(
    input: &Input,
    source: Source,
    layout: &Layout,
    part: &mut [u8],
    options: &ConvertOptions,
) -> Result<()> {
    use std::os::unix::fs::FileExt;
    let file = input.path.display().to_string();
    let raw = input
        .header
        .clone()
        .into_raw()
        .map_err(|e| anyhow::anyhow!("{file}: invalid LAS header: {e}"))?;
    let start = u64::from(raw.offset_to_point_data);
    let handle =
        std::fs::File::open(&input.path).with_context(|| format!("{file}: cannot open"))?;
    let size = handle
        .metadata()
        .with_context(|| format!("{file}: cannot read its size"))?
        .len();
    let end = start + input.points * source.len as u64;
    if end > size {
        bail!(
            "{file}: the header declares {} points of {} bytes from byte {start}, but the file ends at byte {size} (truncated file?)",
            input.points,
            source.len
        );
    }
    let len = layout.record_len();
    part.par_chunks_mut(BLOCK_POINTS as usize * len)
        .enumerate()
        .try_for_each_init(Vec::new, |buf, (block, dst)| {
            if options.stopped() {
                bail!("interrupted");
            }
            let first = block as u64 * BLOCK_POINTS;
            let at = start + first * source.len as u64;
            let n = dst.len() / len;
            if source.is_identity(layout) {
                return handle
                    .read_exact_at(dst, at)
                    .with_context(|| format!("{file}: cannot read point record {first}"));
            }
            buf.resize(n * source.len, 0);
            handle
                .read_exact_at(buf, at)
                .with_context(|| format!("{file}: cannot read point record {first}"))?;
            source.transcode(layout, buf, dst);
            Ok(())
        })
}

fn read_compressed(
    input: &Input,
    source: Source,
    layout: &Layout,
    part: &mut [u8],
    options: &ConvertOptions,
) -> Result<()> {
    let file = input.path.display().to_string();
    let len = layout.record_len();
    crate::scene::guard::deep_stack(|| -> Result<()> {
        let Some(mut reader) = crate::scene::las::open_blocks(&input.path)? else {
            bail!("{file}: cannot be read in blocks");
        };
        let mut data = las::PointDataBuilder::new()
            .for_header(reader.header())
            .build();
        let mut done = 0u64;
        while done < input.points {
            if options.stopped() {
                bail!("interrupted");
            }
            let want = BLOCK_POINTS.min(input.points - done);
            let n = crate::scene::guard::third_party(|| reader.fill_points(want, &mut data))
                .map_err(|e| anyhow::anyhow!("{file}: point record {done}: {e}"))?
                .map_err(|e| anyhow::anyhow!("{file}: point record {done}: {e}"))?;
            if n == 0 {
                bail!(
                    "{file}: the header declares {} points, the file holds {done} (truncated file?)",
                    input.points
                );
            }
            let at = done as usize * len;
            source.transcode(
                layout,
                data.raw_bytes(),
                &mut part[at..at + n as usize * len],
            );
            done += n;
        }
        Ok(())
    })
}

/// Writes `cloud` as the COPC file `out`.
pub fn write(cloud: &Cloud, out: &Path) -> Result<()> {
    write_with(cloud, out, DEFAULT_NODE_POINTS)
}

/// [`write`] with `node_points` points per node.
pub fn write_with(cloud: &Cloud, out: &Path, node_points: u32) -> Result<()> {
    let (layout, records) = records::encode_cloud(cloud)?;
    copc_write::write(out, &layout, &records, node_points, &|| false)?;
    Ok(())
}

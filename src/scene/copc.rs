//! COPC reader (Cloud Optimized Point Cloud: a LAS 1.4 LAZ file whose points are stored as an
//! octree, one LAZ chunk per node, with a hierarchy of nodes in an EVLR).
//!
//! The header and VLRs are read by the `las` crate; the COPC info VLR, the hierarchy pages and
//! the chunks are read here, and each chunk is decompressed on its own (in parallel) with the
//! `laz` crate's layered decompressor. With a point budget the octree is read breadth-first by
//! level: level 0 always, then each next level while the running total stays within the
//! budget; [`LoadStats::levels`] records the points of every level and how many were read.
//! Coordinates, colors, intensity, classification, returns, point source and GPS time are
//! converted as for LAS (f64 until the
//! bounding-box centre is subtracted; 8-bit colors in 16-bit fields detected).
//!
//! Every offset and size in the file is checked against the file's length before anything is
//! allocated for it, and a chunk's layer sizes against the chunk, so a corrupt or truncated
//! file fails with the byte offset of what is wrong.

use std::fs::File;
use std::io::{BufReader, Cursor, ErrorKind, Read, Seek, SeekFrom};
use std::path::Path;

use glam::{DVec3, Vec3};
use laz::record::{LayeredPointRecordDecompressor, RecordDecompressor};
use laz::{LazItem, LazItemType, LazVlr};
use rayon::prelude::*;

use super::cloud::{Bounds, Cloud, Levels, LoadStats, Scalar};
use super::error::LoadError;
use super::guard;
use super::progress::Progress;

/// Bytes of one hierarchy entry: key (4 × i32), offset (u64), byte size (i32), point count (i32).
const ENTRY_BYTES: usize = 32;

/// Bytes of the COPC info VLR's payload.
const INFO_BYTES: usize = 160;

/// Deepest octree level accepted (a 2^31-wide grid already exceeds any real survey).
const MAX_LEVEL: i32 = 31;

/// Points a chunk may declare per compressed byte: LAZ cannot store points more densely
/// (each point costs at least a few bits in every layer), so more means a corrupt count.
const MAX_POINTS_PER_BYTE: u64 = 64;

/// Compressed bytes read from the file per batch of chunks decoded in parallel.
const BATCH_BYTES: u64 = 64 << 20;

/// Chunks with at least this many points in all show a progress bar (on a terminal).
const PROGRESS_MIN_POINTS: u64 = 5_000_000;

/// One octree node with points.
#[derive(Clone, Copy, Debug)]
struct Node {
    level: usize,
    offset: u64,
    bytes: u64,
    points: u64,
    /// Where the node's hierarchy entry is (for error messages).
    entry_at: u64,
}

/// The points of decoded chunks, before the origin is known.
#[derive(Default)]
struct Decoded {
    world: Vec<DVec3>,
    rgb16: Vec<[u16; 3]>,
    /// The standard fields, in the order of [`super::las::STANDARD_NAMES`]; `gps_time` follows.
    standard: [Vec<f32>; 5],
    gps_time: Vec<f64>,
}

fn io_error(file: &str, source: std::io::Error) -> LoadError {
    LoadError::Io {
        file: file.to_owned(),
        source,
    }
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut raw = [0u8; 8];
    raw.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(raw)
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Reads `len` bytes at `at` of a file of `size` bytes; `what` names them in the error when
/// they lie past the end.
fn read_at<R: Read + Seek>(
    file: &str,
    read: &mut R,
    at: u64,
    len: u64,
    size: u64,
    what: &str,
) -> Result<Vec<u8>, LoadError> {
    if at.saturating_add(len) > size {
        return Err(LoadError::parse(
            file,
            super::Location::ByteOffset(at),
            format!(
                "{what} ({len} bytes) ends past the end of the file at byte {size} (truncated file?)"
            ),
        ));
    }
    let mut bytes = vec![0; len as usize];
    read.seek(SeekFrom::Start(at))
        .and_then(|_| read.read_exact(&mut bytes))
        .map_err(|source| io_error(file, source))?;
    Ok(bytes)
}

/// Checks the parts of a LAS 1.4 header that the `las` crate would trust: the point count must
/// fit the file, and the first EVLR must lie inside it (so no record length the file cannot
/// hold is allocated).
fn check_header<R: Read + Seek>(file: &str, read: &mut R, size: u64) -> Result<(), LoadError> {
    let header = read_at(file, read, 0, 375.min(size), size, "the LAS header")?;
    if header.len() < 375 || &header[..4] != b"LASF" {
        return Err(LoadError::at_byte(
            file,
            0,
            format!(
                "expected a LAS 1.4 header (375 bytes starting with \"LASF\"), found {} bytes",
                header.len()
            ),
        ));
    }
    if (header[24], header[25]) != (1, 4) {
        return Err(LoadError::at_byte(
            file,
            24,
            format!(
                "expected LAS version 1.4 (COPC), found {}.{}",
                header[24], header[25]
            ),
        ));
    }
    let (count_at, count) = match u32_at(&header, 107) {
        0 => (247, u64_at(&header, 247)),
        legacy => (107, u64::from(legacy)),
    };
    if count > size.saturating_mul(MAX_POINTS_PER_BYTE) {
        return Err(LoadError::at_byte(
            file,
            count_at,
            format!(
                "the header declares {count} points, more than a file of {size} bytes can hold"
            ),
        ));
    }
    let start = u64_at(&header, 235);
    if u32_at(&header, 243) == 0 {
        return Ok(());
    }
    let evlr = read_at(file, read, start, 60, size, "the first EVLR header")?;
    let len = u64_at(&evlr, 20);
    if start.saturating_add(60).saturating_add(len) > size {
        return Err(LoadError::at_byte(
            file,
            start as usize + 20,
            format!(
                "the first EVLR ({len} bytes) ends past the end of the file at byte {size} (truncated file?)"
            ),
        ));
    }
    Ok(())
}

/// The hierarchy's nodes with points, in breadth-first page order, from the root page at
/// `root` (`len` bytes). Pages are visited once each; entries are checked against the file.
fn hierarchy<R: Read + Seek>(
    file: &str,
    read: &mut R,
    root: (u64, u64),
    size: u64,
) -> Result<Vec<Node>, LoadError> {
    let mut nodes = Vec::new();
    let mut pages = std::collections::VecDeque::from([root]);
    let mut seen = std::collections::HashSet::new();
    while let Some((at, len)) = pages.pop_front() {
        if !seen.insert(at) {
            return Err(LoadError::at_byte(
                file,
                at as usize,
                "a hierarchy page is referenced twice (the hierarchy has a cycle)",
            ));
        }
        if len % ENTRY_BYTES as u64 != 0 {
            return Err(LoadError::at_byte(
                file,
                at as usize,
                format!("hierarchy page of {len} bytes; expected a multiple of {ENTRY_BYTES}"),
            ));
        }
        let page = read_at(file, read, at, len, size, "the hierarchy page")?;
        for (i, entry) in page.chunks_exact(ENTRY_BYTES).enumerate() {
            let entry_at = at + (i * ENTRY_BYTES) as u64;
            let level = i32_at(entry, 0);
            let offset = u64_at(entry, 16);
            let bytes = i32_at(entry, 24);
            let points = i32_at(entry, 28);
            let bad = |what: String| LoadError::at_byte(file, entry_at as usize, what);
            if !(0..=MAX_LEVEL).contains(&level) {
                return Err(bad(format!(
                    "hierarchy entry with octree level {level}; expected 0 to {MAX_LEVEL}"
                )));
            }
            match points {
                -1 => {
                    let bytes = u64::try_from(bytes)
                        .map_err(|_| bad(format!("child page of negative size {bytes}")))?;
                    pages.push_back((offset, bytes));
                }
                0 => {}
                n if n > 0 => {
                    let bytes = u64::try_from(bytes).unwrap_or(0);
                    if bytes == 0 || offset.saturating_add(bytes) > size {
                        return Err(bad(format!(
                            "the chunk of {n} points ({bytes} bytes at byte {offset}) is not inside the file of {size} bytes (truncated file?)"
                        )));
                    }
                    if n as u64 > bytes * MAX_POINTS_PER_BYTE {
                        return Err(bad(format!(
                            "a chunk of {bytes} bytes cannot hold the {n} points it declares"
                        )));
                    }
                    nodes.push(Node {
                        level: level as usize,
                        offset,
                        bytes,
                        points: n as u64,
                        entry_at,
                    });
                }
                n => return Err(bad(format!("hierarchy entry with point count {n}"))),
            }
        }
    }
    Ok(nodes)
}

/// The levels to read: level 0, then each next level while the running total stays within
/// `budget` (all levels without one).
pub fn select_levels(points: &[u64], budget: Option<u64>) -> usize {
    let Some(budget) = budget else {
        return points.len();
    };
    let mut total = 0u64;
    let mut read = 0;
    for &n in points {
        total = total.saturating_add(n);
        if read > 0 && total > budget {
            break;
        }
        read += 1;
    }
    read
}

/// The number of LAZ layers each item of the point format stores after the chunk's first point.
fn layers(items: &[LazItem]) -> Option<usize> {
    items
        .iter()
        .map(|item| match item.item_type() {
            LazItemType::Point14 => Some(9),
            LazItemType::RGB14 | LazItemType::WavePacket14 => Some(1),
            LazItemType::RGBNIR14 => Some(2),
            LazItemType::Byte14(n) => Some(usize::from(n)),
            _ => None,
        })
        .sum()
}

/// Decodes one chunk (`data`, the node's bytes) into its points.
fn decode_chunk(
    file: &str,
    node: &Node,
    data: &[u8],
    header: &las::Header,
    vlr: &LazVlr,
    layer_count: usize,
) -> Result<Decoded, LoadError> {
    let format = header.point_format();
    let stride = usize::from(format.len());
    let at = |extra: usize| node.offset as usize + extra;
    // First point (raw), point count, layer sizes, then the layers.
    let sizes_at = stride + 4;
    let layers_at = sizes_at + 4 * layer_count;
    if data.len() < layers_at {
        return Err(LoadError::at_byte(
            file,
            at(0),
            format!(
                "chunk of {} bytes is too short for its first point and layer sizes ({layers_at} bytes)",
                data.len()
            ),
        ));
    }
    let count = u64::from(u32_at(data, stride));
    if count != node.points {
        return Err(LoadError::at_byte(
            file,
            at(stride),
            format!(
                "the chunk holds {count} points, but its hierarchy entry at byte {} declares {}",
                node.entry_at, node.points
            ),
        ));
    }
    let layer_bytes: u64 = (0..layer_count)
        .map(|i| u64::from(u32_at(data, sizes_at + 4 * i)))
        .sum();
    if layers_at as u64 + layer_bytes > data.len() as u64 {
        return Err(LoadError::at_byte(
            file,
            at(sizes_at),
            format!(
                "the chunk's layers need {layer_bytes} bytes, but only {} follow the layer sizes",
                data.len() - layers_at
            ),
        ));
    }
    let mut decompressor = LayeredPointRecordDecompressor::new(Cursor::new(data));
    let corrupt = |e: String| LoadError::at_byte(file, at(0), format!("corrupt LAZ chunk: {e}"));
    let mut records = vec![0u8; node.points as usize * stride];
    guard::third_party(|| {
        decompressor
            .set_fields_from(vlr.items())
            .map_err(|e| e.to_string())?;
        decompressor
            .decompress_many(&mut records)
            .map_err(|e| e.to_string())
    })
    .map_err(&corrupt)?
    .map_err(corrupt)?;
    let mut out = Decoded::default();
    let transforms = header.transforms();
    for record in records.chunks_exact(stride) {
        let raw = las::raw::Point::read_from(record, format).map_err(|e| corrupt(e.to_string()))?;
        let p = las::Point::new(raw, transforms);
        out.world.push(DVec3::new(p.x, p.y, p.z));
        if let Some(c) = p.color {
            out.rgb16.push([c.red, c.green, c.blue]);
        }
        for (column, value) in out.standard.iter_mut().zip(super::las::standard_values(&p)) {
            column.push(value);
        }
        out.gps_time.push(p.gps_time.unwrap_or(0.0));
    }
    Ok(out)
}

/// Loads a COPC file, reading only the octree levels that fit `budget` points when one is given.
pub fn load(path: &Path, budget: Option<u64>) -> Result<Cloud, LoadError> {
    let file = path.display().to_string();
    let open = File::open(path).map_err(|source| io_error(&file, source))?;
    let size = open
        .metadata()
        .map_err(|source| io_error(&file, source))?
        .len();
    let mut read = BufReader::new(open);
    check_header(&file, &mut read, size)?;
    read.rewind().map_err(|source| io_error(&file, source))?;
    let header = guard::third_party(|| las::Header::new(&mut read))
        .map_err(|e| LoadError::whole(&file, format!("invalid LAS header: {e}")))?
        .map_err(|e| match e {
        las::Error::Io(e) if e.kind() == ErrorKind::UnexpectedEof => LoadError::whole(
            &file,
            format!("invalid LAS header: the file ends at byte {size}, inside the header or its VLRs (truncated file?)"),
        ),
        las::Error::Io(source) => io_error(&file, source),
        e => LoadError::whole(&file, format!("invalid LAS header: {e}")),
    })?;
    let info = header
        .vlrs()
        .iter()
        .find(|v| v.is_copc_info())
        .ok_or_else(|| {
            LoadError::whole(
                &file,
                "not a COPC file: expected a COPC info VLR (user id \"copc\", record 1)",
            )
        })?;
    if info.data.len() < INFO_BYTES {
        return Err(LoadError::whole(
            &file,
            format!(
                "COPC info VLR of {} bytes; expected {INFO_BYTES}",
                info.data.len()
            ),
        ));
    }
    let root = (u64_at(&info.data, 40), u64_at(&info.data, 48));
    let vlr = header
        .laz_vlr()
        .map_err(|e| LoadError::whole(&file, format!("COPC file without a valid LAZ VLR: {e}")))?;
    let layer_count = layers(vlr.items()).ok_or_else(|| {
        LoadError::whole(
            &file,
            "the LAZ VLR lists an item a COPC (point format 6-10, layered) chunk cannot hold",
        )
    })?;
    let nodes = hierarchy(&file, &mut read, root, size)?;
    let declared: u64 = nodes.iter().map(|n| n.points).sum();
    if declared != header.number_of_points() {
        return Err(LoadError::whole(
            &file,
            format!(
                "the COPC hierarchy holds {declared} points, but the header declares {}",
                header.number_of_points()
            ),
        ));
    }
    let depth = nodes.iter().map(|n| n.level + 1).max().unwrap_or(0);
    let mut per_level = vec![0u64; depth];
    for n in &nodes {
        per_level[n.level] += n.points;
    }
    let levels = Levels {
        read: select_levels(&per_level, budget),
        points: per_level,
    };
    let mut chosen: Vec<Node> = nodes
        .into_iter()
        .filter(|n| n.level < levels.read)
        .collect();
    chosen.sort_by_key(|n| n.level);
    let total = levels.points_read();
    let progress = Progress::new("loading", total as usize, total >= PROGRESS_MIN_POINTS);
    let mut decoded = Decoded::default();
    let mut start = 0;
    while start < chosen.len() {
        let mut end = start;
        let mut bytes = 0;
        while end < chosen.len() && (end == start || bytes + chosen[end].bytes <= BATCH_BYTES) {
            bytes += chosen[end].bytes;
            end += 1;
        }
        let batch = &chosen[start..end];
        let data = batch
            .iter()
            .map(|n| read_at(&file, &mut read, n.offset, n.bytes, size, "the chunk"))
            .collect::<Result<Vec<_>, _>>()?;
        let parts = guard::deep_stack(|| {
            batch
                .par_iter()
                .zip(&data)
                .map(|(node, data)| {
                    let part = decode_chunk(&file, node, data, &header, &vlr, layer_count);
                    progress.advance(node.points as usize);
                    part
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        for part in parts {
            decoded.world.extend(part.world);
            decoded.rgb16.extend(part.rgb16);
            for (all, column) in decoded.standard.iter_mut().zip(part.standard) {
                all.extend(column);
            }
            decoded.gps_time.extend(part.gps_time);
        }
        start = end;
    }
    progress.finish();
    Ok(finish(decoded, levels, header.number_of_points()))
}

/// The cloud of the decoded points: re-centred on the f64 bounding-box centre.
fn finish(decoded: Decoded, levels: Levels, declared: u64) -> Cloud {
    let bounds = decoded.world.iter().fold(Bounds::EMPTY, |mut b, p| {
        b.add(*p);
        b
    });
    let origin = bounds.centre().unwrap_or(DVec3::ZERO);
    let n = decoded.world.len();
    let colors = (decoded.rgb16.len() == n && n > 0).then(|| {
        let eight_bit = decoded.rgb16.iter().flatten().all(|&c| c <= 255);
        decoded
            .rgb16
            .iter()
            .map(|c| {
                let [r, g, b] = c.map(|v| if eight_bit { v as u8 } else { (v >> 8) as u8 });
                [r, g, b, 255]
            })
            .collect()
    });
    let positions: Vec<Vec3> = decoded
        .world
        .par_iter()
        .map(|p| (*p - origin).as_vec3())
        .collect();
    let mut cloud = Cloud {
        positions,
        colors,
        scalars: super::las::STANDARD_NAMES
            .iter()
            .zip(decoded.standard)
            .map(|(name, values)| Scalar {
                name: (*name).into(),
                values,
            })
            .chain(std::iter::once(Scalar {
                name: "gps_time".into(),
                // Relative to the first point's, as the LAS reader keeps them.
                values: decoded
                    .gps_time
                    .iter()
                    .map(|t| (t - decoded.gps_time.first().copied().unwrap_or(0.0)) as f32)
                    .collect(),
            }))
            .collect(),
        origin,
        stats: LoadStats {
            records: usize::try_from(declared).unwrap_or(usize::MAX),
            levels: Some(levels),
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    cloud.retain_finite();
    cloud
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_takes_whole_levels_and_always_the_root() {
        let levels = [10, 80, 640, 5120];
        assert_eq!(select_levels(&levels, None), 4);
        assert_eq!(select_levels(&levels, Some(1)), 1);
        assert_eq!(select_levels(&levels, Some(89)), 1);
        assert_eq!(select_levels(&levels, Some(90)), 2);
        assert_eq!(select_levels(&levels, Some(729)), 2);
        assert_eq!(select_levels(&levels, Some(730)), 3);
        assert_eq!(select_levels(&levels, Some(u64::MAX)), 4);
        assert_eq!(select_levels(&[], Some(5)), 0);
    }
}

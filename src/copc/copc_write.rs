//! The COPC writer: LAS 1.4 point records (format 6 or 7 and extra bytes) in memory become an
//! octree of LAZ chunks, one per node, with one hierarchy page.
//!
//! The octree is built top-down over the records sorted by 63-bit Morton code (21 bits per
//! axis over the bounding cube): a node with more than `node_points` points keeps every
//! `n / node_points`-th of them in Morton order (a sample as even over its cube as the points
//! are) and hands the others, still sorted, to its 8 children as contiguous runs. Children are
//! built in parallel; nodes are then compressed in parallel, each as one variable-size LAZ
//! chunk by the `laz` crate's layered (point format 6–10) record compressor, and written in
//! the order the tree was built (a node before its children). The file is assembled here: the
//! header, the COPC info VLR first of all VLRs, the laszip VLR, the extra-bytes and carried VLRs,
//! the chunk-table offset, the chunks, the chunk table, and the hierarchy as an EVLR.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use glam::DVec3;
use laz::laszip::{ChunkTable, ChunkTableEntry};
use laz::record::{LayeredPointRecordCompressor, RecordCompressor};
use laz::{LazItemRecordBuilder, LazVlr, LazVlrBuilder};
use rayon::prelude::*;

use crate::scene::copc::Key;
use crate::scene::morton;

/// Octree depth at most: the Morton code's 21 bits per axis.
const MAX_LEVEL: i32 = 21;

/// Bytes of records gathered and compressed per parallel batch of nodes.
const BATCH_BYTES: usize = 32 << 20;

/// Bytes of the LAS 1.4 header.
const HEADER_BYTES: usize = 375;

/// A VLR carried into the output (a CRS, for instance).
#[derive(Clone, Debug, PartialEq)]
pub struct RawVlr {
    pub user_id: String,
    pub record_id: u16,
    pub description: String,
    pub data: Vec<u8>,
}

/// What the output's records look like and how their coordinates are quantized.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// LAS point format: 6, or 7 with colours.
    pub format: u8,
    /// Extra bytes after each record's standard fields.
    pub extra_bytes: u16,
    /// The extra-bytes VLR's descriptors (192 bytes each), describing `extra_bytes`.
    pub descriptors: Vec<[u8; 192]>,
    pub scale: DVec3,
    pub offset: DVec3,
    /// VLRs copied from the input (its CRS).
    pub vlrs: Vec<RawVlr>,
    /// GPS times are standard GPS time, not GPS week time (global encoding bit 0).
    pub standard_gps_time: bool,
}

impl Layout {
    /// Bytes of one record.
    pub fn record_len(&self) -> usize {
        base_len(self.format) + usize::from(self.extra_bytes)
    }

    /// The world position of quantized coordinates.
    pub fn world(&self, q: [i32; 3]) -> DVec3 {
        DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) * self.scale + self.offset
    }
}

/// Bytes of the standard fields of LAS point format `format` (6 to 10; the COPC formats are
/// 6, 7 and 8).
pub fn base_len(format: u8) -> usize {
    match format {
        6 => 30,
        7 => 36,
        8 => 38,
        9 => 59,
        _ => 67,
    }
}

/// What [`write`] did.
#[derive(Clone, Debug, Default)]
pub struct WriteStats {
    pub nodes: usize,
    pub bytes: u64,
    /// Seconds sorting and building the octree.
    pub build_seconds: f64,
    /// Seconds compressing and writing the chunks.
    pub compress_seconds: f64,
}

/// The extremes of a set of records.
#[derive(Clone, Copy, Debug)]
struct Extremes {
    lo: [i32; 3],
    hi: [i32; 3],
    gps: [f64; 2],
    by_return: [u64; 15],
}

impl Extremes {
    const EMPTY: Self = Self {
        lo: [i32::MAX; 3],
        hi: [i32::MIN; 3],
        gps: [f64::INFINITY, f64::NEG_INFINITY],
        by_return: [0; 15],
    };

    fn add(mut self, r: &[u8]) -> Self {
        for (axis, at) in [0, 4, 8].into_iter().enumerate() {
            let v = i32_at(r, at);
            self.lo[axis] = self.lo[axis].min(v);
            self.hi[axis] = self.hi[axis].max(v);
        }
        let t = f64::from_le_bytes(r[22..30].try_into().expect("8 bytes"));
        if t.is_finite() {
            self.gps = [self.gps[0].min(t), self.gps[1].max(t)];
        }
        let ret = usize::from(r[14] & 15);
        if ret > 0 {
            self.by_return[ret - 1] += 1;
        }
        self
    }

    fn merge(mut self, o: Self) -> Self {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(o.lo[a]);
            self.hi[a] = self.hi[a].max(o.hi[a]);
        }
        self.gps = [self.gps[0].min(o.gps[0]), self.gps[1].max(o.gps[1])];
        for (a, b) in self.by_return.iter_mut().zip(o.by_return) {
            *a += b;
        }
        self
    }
}

fn i32_at(r: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(r[at..at + 4].try_into().expect("4 bytes"))
}

/// The bounding cube of the records: its lower corner and edge (at least one quantization
/// step, a hair larger than the largest extent so every point is strictly inside).
fn cube(layout: &Layout, e: &Extremes) -> (DVec3, f64) {
    let lo = layout.world(e.lo);
    let extent = (layout.world(e.hi) - lo).max_element();
    let edge = extent.max(layout.scale.max_element()) * (1.0 + 1e-9);
    (lo, edge)
}

/// One node of the built octree: its key and its records' indices, in Morton order.
struct Built {
    key: Key,
    points: Vec<u32>,
}

/// The index of the `j`-th of `k` evenly spaced samples among `n` items.
fn sample_at(j: usize, k: usize, n: usize) -> usize {
    ((2 * j as u128 + 1) * n as u128 / (2 * k as u128)) as usize
}

/// Builds the subtree of `key` over `items` (Morton code and record index, sorted by code;
/// every code inside `key`'s cube).
fn build(key: Key, items: &mut [(u64, u32)], node_points: usize) -> Vec<Built> {
    let n = items.len();
    if n <= node_points || key.level >= MAX_LEVEL {
        return vec![Built {
            key,
            points: items.iter().map(|&(_, i)| i).collect(),
        }];
    }
    let mut points = Vec::with_capacity(node_points);
    let (mut kept, mut next) = (0, 0);
    for r in 0..n {
        if next < node_points && r == sample_at(next, node_points, n) {
            points.push(items[r].1);
            next += 1;
        } else {
            items[kept] = items[r];
            kept += 1;
        }
    }
    let shift = 3 * (MAX_LEVEL - 1 - key.level);
    let mut rest = &mut items[..kept];
    let mut children = Vec::with_capacity(8);
    for octant in 0..8u64 {
        let end = rest.partition_point(|&(code, _)| (code >> shift) & 7 <= octant);
        let (run, tail) = rest.split_at_mut(end);
        rest = tail;
        if !run.is_empty() {
            let o = octant as i32;
            let child = Key {
                level: key.level + 1,
                x: 2 * key.x + (o & 1),
                y: 2 * key.y + ((o >> 1) & 1),
                z: 2 * key.z + ((o >> 2) & 1),
            };
            children.push((child, run));
        }
    }
    let mut nodes = vec![Built { key, points }];
    nodes.extend(
        children
            .into_par_iter()
            .flat_map_iter(|(child, run)| build(child, run, node_points))
            .collect::<Vec<_>>(),
    );
    nodes
}

/// The laszip VLR of `layout`'s records, with variable-size chunks (one per node).
fn laz_vlr(layout: &Layout) -> Result<LazVlr> {
    let items =
        LazItemRecordBuilder::default_for_point_format_id(layout.format, layout.extra_bytes)
            .map_err(|e| anyhow::anyhow!("point format {}: {e}", layout.format))?;
    Ok(LazVlrBuilder::new(items).with_variable_chunk_size().build())
}

/// The records of `points`, gathered from `records` in their input order, as one LAZ chunk.
/// The input order is usually the scan's: LAZ predicts each field from the previous point's,
/// and GPS times and positions change least from one point to the next along a scan line.
fn compress(vlr: &LazVlr, records: &[u8], len: usize, points: &[u32]) -> std::io::Result<Vec<u8>> {
    let mut order = points.to_vec();
    order.sort_unstable();
    let mut raw = Vec::with_capacity(points.len() * len);
    for i in order {
        let at = i as usize * len;
        raw.extend_from_slice(&records[at..at + len]);
    }
    let mut compressor = LayeredPointRecordCompressor::new(std::io::Cursor::new(Vec::new()));
    compressor
        .set_fields_from(vlr.items())
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    compressor.compress_many(&raw)?;
    compressor.done()?;
    Ok(compressor.into_inner().into_inner())
}

/// A file being written that is removed unless [`Partial::keep`] renames it into place.
struct Partial {
    path: PathBuf,
    out: PathBuf,
    kept: bool,
}

impl Partial {
    fn new(out: &Path) -> Self {
        let name = out
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
        Self {
            path: out.with_file_name(format!(".{name}.{}.part", std::process::id())),
            out: out.to_path_buf(),
            kept: false,
        }
    }

    fn keep(mut self) -> Result<()> {
        std::fs::rename(&self.path, &self.out).with_context(|| {
            format!(
                "{}: cannot move the written file into place",
                self.out.display()
            )
        })?;
        self.kept = true;
        Ok(())
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if !self.kept {
            // Best effort: a file that cannot be removed stays behind as `.NAME.PID.part`.
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Writes `records` (records of `layout`, back to back) as the COPC file `out`, nodes of about
/// `node_points` points. `stopped` is polled between batches of nodes; when it answers true
/// the write fails with "interrupted" and leaves nothing behind.
pub fn write(
    out: &Path,
    layout: &Layout,
    records: &[u8],
    node_points: u32,
    stopped: &(dyn Fn() -> bool + Sync),
) -> Result<WriteStats> {
    let len = layout.record_len();
    let n = records.len() / len;
    if n == 0 {
        bail!("{}: no points to write", out.display());
    }
    if u32::try_from(n).is_err() {
        bail!(
            "{}: {n} points: one COPC file holds at most {} here (write tiles)",
            out.display(),
            u32::MAX
        );
    }
    let start = Instant::now();
    let extremes = records
        .par_chunks(len * 65_536)
        .map(|block| block.chunks_exact(len).fold(Extremes::EMPTY, Extremes::add))
        .reduce(|| Extremes::EMPTY, Extremes::merge);
    let (lo, edge) = cube(layout, &extremes);
    let cells = f64::from(1u32 << MAX_LEVEL);
    let factor = layout.scale * (cells / edge);
    let q_lo = extremes.lo;
    let top = (1u32 << MAX_LEVEL) - 1;
    let mut items: Vec<(u64, u32)> = records
        .par_chunks_exact(len)
        .enumerate()
        .map(|(i, r)| {
            let cell = |axis: usize| {
                let d = f64::from(i32_at(r, 4 * axis)) - f64::from(q_lo[axis]);
                ((d * factor[axis]) as u32).min(top)
            };
            (morton::interleave(cell(0), cell(1), cell(2)), i as u32)
        })
        .collect();
    items.par_sort_unstable();
    let root = Key {
        level: 0,
        x: 0,
        y: 0,
        z: 0,
    };
    let nodes = build(root, &mut items, node_points.max(1) as usize);
    drop(items);
    let build_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();

    let vlr = laz_vlr(layout)?;
    let partial = Partial::new(out);
    let file = File::create(&partial.path).with_context(|| {
        format!(
            "{}: cannot create its temporary file {}",
            out.display(),
            partial.path.display()
        )
    })?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let io = |e: std::io::Error| anyhow::anyhow!("{}: cannot write: {e}", partial.path.display());

    let mut laz_data = Vec::new();
    vlr.write_to(&mut laz_data).map_err(io)?;
    let mut vlrs = vec![RawVlr {
        user_id: "laszip encoded".into(),
        record_id: 22204,
        description: "laz variable chunks".into(),
        data: laz_data,
    }];
    if !layout.descriptors.is_empty() {
        vlrs.push(RawVlr {
            user_id: "LASF_Spec".into(),
            record_id: 4,
            description: "extra bytes".into(),
            data: layout.descriptors.concat(),
        });
    }
    vlrs.extend(layout.vlrs.iter().cloned());
    let point_data =
        HEADER_BYTES + 54 + 160 + vlrs.iter().map(|v| 54 + v.data.len()).sum::<usize>();
    w.write_all(&vec![0u8; point_data + 8]).map_err(io)?;

    let mut table = ChunkTable::with_capacity(nodes.len());
    let mut entries = Vec::with_capacity(nodes.len());
    let mut at = point_data as u64 + 8;
    let mut next = 0;
    while next < nodes.len() {
        if stopped() {
            bail!("{}: interrupted", out.display());
        }
        let mut end = next;
        let mut bytes = 0;
        while end < nodes.len() && (end == next || bytes < BATCH_BYTES) {
            bytes += nodes[end].points.len() * len;
            end += 1;
        }
        let chunks = nodes[next..end]
            .par_iter()
            .map(|node| compress(&vlr, records, len, &node.points))
            .collect::<std::io::Result<Vec<_>>>()
            .map_err(io)?;
        for (node, chunk) in nodes[next..end].iter().zip(chunks) {
            w.write_all(&chunk).map_err(io)?;
            let size = chunk.len() as u64;
            table.push(ChunkTableEntry {
                point_count: node.points.len() as u64,
                byte_count: size,
            });
            entries.push((node.key, at, size, node.points.len()));
            at += size;
        }
        next = end;
    }
    let table_at = at;
    table.write_to(&mut w, &vlr).map_err(io)?;
    let evlr_at = w.stream_position().map_err(io)?;
    let hierarchy_bytes = entries.len() * 32;
    write_vlr_header(&mut w, true, "copc", 1000, hierarchy_bytes, "EPT hierarchy").map_err(io)?;
    for (key, offset, size, count) in &entries {
        for v in [key.level, key.x, key.y, key.z] {
            w.write_all(&v.to_le_bytes()).map_err(io)?;
        }
        w.write_all(&offset.to_le_bytes()).map_err(io)?;
        w.write_all(&(*size as i32).to_le_bytes()).map_err(io)?;
        w.write_all(&(*count as i32).to_le_bytes()).map_err(io)?;
    }
    let file_bytes = w.stream_position().map_err(io)?;
    if stopped() {
        bail!("{}: interrupted", out.display());
    }

    w.seek(SeekFrom::Start(0)).map_err(io)?;
    let mut head = Vec::with_capacity(point_data + 8);
    header(
        &mut head,
        layout,
        &extremes,
        n as u64,
        point_data,
        1 + vlrs.len(),
        evlr_at,
    );
    let center = lo + DVec3::splat(edge / 2.0);
    write_vlr_header(&mut head, false, "copc", 1, 160, "copc info").map_err(io)?;
    for v in [center.x, center.y, center.z, edge / 2.0, edge / 2.0 / 128.0] {
        head.extend_from_slice(&v.to_le_bytes());
    }
    head.extend_from_slice(&(evlr_at + 60).to_le_bytes());
    head.extend_from_slice(&(hierarchy_bytes as u64).to_le_bytes());
    let gps = if extremes.gps[0] <= extremes.gps[1] {
        extremes.gps
    } else {
        [0.0; 2]
    };
    for v in gps {
        head.extend_from_slice(&v.to_le_bytes());
    }
    head.extend_from_slice(&[0u8; 88]);
    for v in &vlrs {
        write_vlr_header(
            &mut head,
            false,
            &v.user_id,
            v.record_id,
            v.data.len(),
            &v.description,
        )
        .map_err(io)?;
        head.extend_from_slice(&v.data);
    }
    head.extend_from_slice(&table_at.to_le_bytes());
    debug_assert_eq!(head.len(), point_data + 8);
    w.write_all(&head).map_err(io)?;
    w.into_inner()
        .map_err(|e| io(e.into_error()))?
        .sync_all()
        .map_err(io)?;
    partial.keep()?;
    Ok(WriteStats {
        nodes: entries.len(),
        bytes: file_bytes,
        build_seconds,
        compress_seconds: start.elapsed().as_secs_f64(),
    })
}

/// A VLR's (54 bytes) or an EVLR's (60 bytes) header.
fn write_vlr_header(
    w: &mut impl Write,
    extended: bool,
    user_id: &str,
    record_id: u16,
    len: usize,
    description: &str,
) -> std::io::Result<()> {
    let text = |s: &str, n: usize| {
        let mut b = vec![0u8; n];
        let s = s.as_bytes();
        let k = s.len().min(n);
        b[..k].copy_from_slice(&s[..k]);
        b
    };
    w.write_all(&[0, 0])?;
    w.write_all(&text(user_id, 16))?;
    w.write_all(&record_id.to_le_bytes())?;
    if extended {
        w.write_all(&(len as u64).to_le_bytes())?;
    } else {
        let len = u16::try_from(len).map_err(|_| {
            std::io::Error::other(format!("a VLR of {len} bytes is longer than 65,535"))
        })?;
        w.write_all(&len.to_le_bytes())?;
    }
    w.write_all(&text(description, 32))
}

/// Today as (day of the year, counting from 1; year), from the system clock.
fn today() -> (u16, u16) {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400);
    day_of_year(days)
}

/// The day `days` after 1 January 1970 as (day of the year, counting from 1; year).
fn day_of_year(days: u64) -> (u16, u16) {
    let mut year = 1970;
    let mut left = days;
    loop {
        let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
        let length = if leap { 366 } else { 365 };
        if left < length {
            return ((left + 1) as u16, year as u16);
        }
        left -= length;
        year += 1;
    }
}

/// The LAS 1.4 header (375 bytes) of the output.
fn header(
    h: &mut Vec<u8>,
    layout: &Layout,
    e: &Extremes,
    points: u64,
    point_data: usize,
    vlr_count: usize,
    evlr_at: u64,
) {
    let text = |h: &mut Vec<u8>, s: &str, n: usize| {
        let mut b = vec![0u8; n];
        b[..s.len().min(n)].copy_from_slice(&s.as_bytes()[..s.len().min(n)]);
        h.extend_from_slice(&b);
    };
    h.extend_from_slice(b"LASF");
    h.extend_from_slice(&0u16.to_le_bytes());
    let encoding = 0x10 | u16::from(layout.standard_gps_time);
    h.extend_from_slice(&encoding.to_le_bytes());
    h.extend_from_slice(&[0u8; 16]);
    h.extend_from_slice(&[1, 4]);
    text(h, "surfel", 32);
    text(h, &format!("surfel {}", env!("CARGO_PKG_VERSION")), 32);
    let (day, year) = today();
    h.extend_from_slice(&day.to_le_bytes());
    h.extend_from_slice(&year.to_le_bytes());
    h.extend_from_slice(&(HEADER_BYTES as u16).to_le_bytes());
    h.extend_from_slice(&(point_data as u32).to_le_bytes());
    h.extend_from_slice(&(vlr_count as u32).to_le_bytes());
    h.push(layout.format | 0x80);
    h.extend_from_slice(&(layout.record_len() as u16).to_le_bytes());
    h.extend_from_slice(&[0u8; 4 + 20]);
    for v in layout
        .scale
        .to_array()
        .into_iter()
        .chain(layout.offset.to_array())
    {
        h.extend_from_slice(&v.to_le_bytes());
    }
    let (lo, hi) = (layout.world(e.lo), layout.world(e.hi));
    for axis in 0..3 {
        h.extend_from_slice(&hi[axis].to_le_bytes());
        h.extend_from_slice(&lo[axis].to_le_bytes());
    }
    h.extend_from_slice(&0u64.to_le_bytes());
    h.extend_from_slice(&evlr_at.to_le_bytes());
    h.extend_from_slice(&1u32.to_le_bytes());
    h.extend_from_slice(&points.to_le_bytes());
    for count in e.by_return {
        h.extend_from_slice(&count.to_le_bytes());
    }
    debug_assert_eq!(h.len(), HEADER_BYTES);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_evenly_spaced_and_distinct() {
        let picked: Vec<usize> = (0..4).map(|j| sample_at(j, 4, 10)).collect();
        assert_eq!(picked, [1, 3, 6, 8]);
        let all: Vec<usize> = (0..10).map(|j| sample_at(j, 10, 11)).collect();
        assert_eq!(all, [0, 1, 2, 3, 4, 6, 7, 8, 9, 10]);
    }

    #[test]
    fn the_calendar_counts_leap_years() {
        assert_eq!(day_of_year(0), (1, 1970));
        assert_eq!(day_of_year(20_088), (366, 2024));
        assert_eq!(day_of_year(11_017), (61, 2000));
    }
}

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
//!
//! The pieces (opening a file's header, reading one hierarchy page, decoding one node) work
//! on any [`ByteSource`], so the streaming reader (`crate::copc`) uses them on a local file
//! or an HTTP server, a page or a node at a time.

use std::io::Cursor;
use std::path::Path;

use glam::{DVec3, Vec3};
use laz::record::{LayeredPointRecordDecompressor, RecordDecompressor};
use laz::{LazItem, LazItemType, LazVlr};
use rayon::prelude::*;

use super::cloud::{Bounds, Cloud, Levels, LoadStats, Scalar};
use super::error::LoadError;
use super::guard;
use super::las::ExtraField;
use super::progress::Progress;
use crate::source::{ByteSource, FileSource};

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

/// An octree node's key: its level and its cell at that level (0 to 2^level - 1 per axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Key {
    pub level: i32,
    pub x: i32,
    pub y: i32,
    pub z: i32,
}

impl Key {
    pub const ROOT: Key = Key {
        level: 0,
        x: 0,
        y: 0,
        z: 0,
    };

    /// The key of the parent (the root is its own parent).
    pub fn parent(self) -> Key {
        if self.level == 0 {
            return self;
        }
        Key {
            level: self.level - 1,
            x: self.x >> 1,
            y: self.y >> 1,
            z: self.z >> 1,
        }
    }

    /// The eight children.
    pub fn children(self) -> [Key; 8] {
        std::array::from_fn(|i| Key {
            level: self.level + 1,
            x: 2 * self.x + (i & 1) as i32,
            y: 2 * self.y + ((i >> 1) & 1) as i32,
            z: 2 * self.z + ((i >> 2) & 1) as i32,
        })
    }
}

impl std::fmt::Display for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{}-{}-{}", self.level, self.x, self.y, self.z)
    }
}

/// One octree node with points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Node {
    pub key: Key,
    pub offset: u64,
    pub bytes: u64,
    pub points: u64,
    /// Where the node's hierarchy entry is (for error messages).
    pub entry_at: u64,
}

/// One entry of a hierarchy page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// A node with points.
    Node(Node),
    /// The page holding the entries of `key` and below (`bytes` at `offset`).
    Page { key: Key, offset: u64, bytes: u64 },
}

/// The COPC info VLR: the octree's cube and the root hierarchy page.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Info {
    /// Centre of the root cube (file coordinates).
    pub center: DVec3,
    /// Half the root cube's edge.
    pub halfsize: f64,
    /// Spacing of the root node's points; halved per level.
    pub spacing: f64,
    /// The root hierarchy page: byte offset and size.
    pub root: (u64, u64),
    /// GPS time range of the points.
    pub gps_time: (f64, f64),
}

impl Info {
    /// The file-coordinate bounds of node `key`'s cube.
    pub fn cube(&self, key: Key) -> (DVec3, DVec3) {
        let edge = 2.0 * self.halfsize / f64::from(1u32 << key.level.clamp(0, 31));
        let lo = self.center - DVec3::splat(self.halfsize)
            + DVec3::new(f64::from(key.x), f64::from(key.y), f64::from(key.z)) * edge;
        (lo, lo + DVec3::splat(edge))
    }
}

/// An opened COPC file: its header, octree info and what decoding a node needs.
pub struct CopcFile {
    pub file: String,
    pub size: u64,
    pub header: las::Header,
    pub info: Info,
    vlr: LazVlr,
    layer_count: usize,
    pub(crate) extra: Vec<ExtraField>,
}

/// The points of decoded chunks, before the origin is known.
#[derive(Default)]
pub struct Decoded {
    pub world: Vec<DVec3>,
    pub rgb16: Vec<[u16; 3]>,
    /// The standard fields, in the order of [`super::las::STANDARD_NAMES`]; `gps_time` follows.
    pub standard: [Vec<f32>; 5],
    pub gps_time: Vec<f64>,
    /// The extra-bytes fields, in the order of [`CopcFile::extra`].
    pub extra: Vec<Vec<f32>>,
}

impl Decoded {
    fn append(&mut self, part: Decoded) {
        self.world.extend(part.world);
        self.rgb16.extend(part.rgb16);
        for (all, column) in self.standard.iter_mut().zip(part.standard) {
            all.extend(column);
        }
        self.gps_time.extend(part.gps_time);
        if self.extra.len() < part.extra.len() {
            self.extra.resize_with(part.extra.len(), Vec::new);
        }
        for (all, column) in self.extra.iter_mut().zip(part.extra) {
            all.extend(column);
        }
    }
}

fn source_error(e: crate::source::SourceError) -> LoadError {
    LoadError::whole("", e.message)
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
fn read_at(
    file: &str,
    read: &dyn ByteSource,
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
    read.read_at(at, len).map_err(source_error)
}

/// Checks the parts of a LAS 1.4 header that the `las` crate would trust: the point count must
/// fit the file, and the first EVLR must lie inside it (so no record length the file cannot
/// hold is allocated).
fn check_header(file: &str, read: &dyn ByteSource, size: u64) -> Result<(), LoadError> {
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

/// The entries of the hierarchy page of `len` bytes at `at`, checked against the file of
/// `size` bytes: levels 0 to [`MAX_LEVEL`] with cells inside their level's grid, chunks inside
/// the file and no denser than LAZ can store, child pages of non-negative size.
pub fn read_page(
    file: &str,
    read: &dyn ByteSource,
    at: u64,
    len: u64,
    size: u64,
) -> Result<Vec<Entry>, LoadError> {
    if !len.is_multiple_of(ENTRY_BYTES as u64) {
        return Err(LoadError::at_byte(
            file,
            at as usize,
            format!("hierarchy page of {len} bytes; expected a multiple of {ENTRY_BYTES}"),
        ));
    }
    let page = read_at(file, read, at, len, size, "the hierarchy page")?;
    let mut entries = Vec::with_capacity(page.len() / ENTRY_BYTES);
    for (i, entry) in page.chunks_exact(ENTRY_BYTES).enumerate() {
        let entry_at = at + (i * ENTRY_BYTES) as u64;
        let key = Key {
            level: i32_at(entry, 0),
            x: i32_at(entry, 4),
            y: i32_at(entry, 8),
            z: i32_at(entry, 12),
        };
        let offset = u64_at(entry, 16);
        let bytes = i32_at(entry, 24);
        let points = i32_at(entry, 28);
        let bad = |what: String| LoadError::at_byte(file, entry_at as usize, what);
        if !(0..=MAX_LEVEL).contains(&key.level) {
            return Err(bad(format!(
                "hierarchy entry with octree level {}; expected 0 to {MAX_LEVEL}",
                key.level
            )));
        }
        let cells = 1i64 << key.level;
        if [key.x, key.y, key.z]
            .iter()
            .any(|&c| !(0..cells).contains(&i64::from(c)))
        {
            return Err(bad(format!(
                "hierarchy entry {key}: a cell outside level {}'s grid of {cells} per axis",
                key.level
            )));
        }
        match points {
            -1 => {
                let bytes = u64::try_from(bytes)
                    .map_err(|_| bad(format!("child page of negative size {bytes}")))?;
                entries.push(Entry::Page { key, offset, bytes });
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
                entries.push(Entry::Node(Node {
                    key,
                    offset,
                    bytes,
                    points: n as u64,
                    entry_at,
                }));
            }
            n => return Err(bad(format!("hierarchy entry with point count {n}"))),
        }
    }
    Ok(entries)
}

/// The hierarchy's nodes with points, in breadth-first page order, from the root page. Pages
/// are visited once each.
fn hierarchy(copc: &CopcFile, read: &dyn ByteSource) -> Result<Vec<Node>, LoadError> {
    let mut nodes = Vec::new();
    let mut pages = std::collections::VecDeque::from([copc.info.root]);
    let mut seen = std::collections::HashSet::new();
    while let Some((at, len)) = pages.pop_front() {
        if !seen.insert(at) {
            return Err(LoadError::at_byte(
                &copc.file,
                at as usize,
                "a hierarchy page is referenced twice (the hierarchy has a cycle)",
            ));
        }
        for entry in read_page(&copc.file, read, at, len, copc.size)? {
            match entry {
                Entry::Node(n) => nodes.push(n),
                Entry::Page { offset, bytes, .. } => pages.push_back((offset, bytes)),
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

impl CopcFile {
    /// Reads and checks the header, the VLRs and the COPC info of the COPC file in `read`.
    /// Only the bytes before the point data are read: the hierarchy is reached through the
    /// info VLR, not the EVLR list.
    pub fn open(read: &dyn ByteSource) -> Result<Self, LoadError> {
        let file = read.name().to_owned();
        let size = read.len();
        check_header(&file, read, size)?;
        let start = u64::from(u32_at(
            &read_at(&file, read, 96, 4, size, "the offset to the point data")?,
            0,
        ));
        let mut prefix = read_at(
            &file,
            read,
            0,
            start.max(375),
            size,
            "the header and its VLRs",
        )?;
        // No EVLRs for the `las` crate: it would read the first one whole.
        prefix[243..247].fill(0);
        let header = guard::third_party(|| las::Header::new(Cursor::new(&prefix)))
            .map_err(|e| LoadError::whole(&file, format!("invalid LAS header: {e}")))?
            .map_err(|e| LoadError::whole(&file, format!("invalid LAS header: {e}")))?;
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
        let f64_at = |at: usize| f64::from_bits(u64_at(&info.data, at));
        let info = Info {
            center: DVec3::new(f64_at(0), f64_at(8), f64_at(16)),
            halfsize: f64_at(24),
            spacing: f64_at(32),
            root: (u64_at(&info.data, 40), u64_at(&info.data, 48)),
            gps_time: (f64_at(56), f64_at(64)),
        };
        if !(info.center.is_finite() && info.halfsize.is_finite() && info.halfsize > 0.0) {
            return Err(LoadError::whole(
                &file,
                format!(
                    "COPC info: the octree cube (centre {}, half size {}) is not finite and positive",
                    info.center, info.halfsize
                ),
            ));
        }
        let vlr = header.laz_vlr().map_err(|e| {
            LoadError::whole(&file, format!("COPC file without a valid LAZ VLR: {e}"))
        })?;
        let layer_count = layers(vlr.items()).ok_or_else(|| {
            LoadError::whole(
                &file,
                "the LAZ VLR lists an item a COPC (point format 6-10, layered) chunk cannot hold",
            )
        })?;
        let extra = super::las::extra_fields(&file, &header)?;
        Ok(Self {
            file,
            size,
            header,
            info,
            vlr,
            layer_count,
            extra,
        })
    }

    /// Whether the points have colours.
    pub fn has_color(&self) -> bool {
        self.header.point_format().has_color
    }

    /// Reads and decodes `node` from `read`.
    pub fn read_node(&self, read: &dyn ByteSource, node: &Node) -> Result<Decoded, LoadError> {
        let data = self.read_chunk(read, node)?;
        self.decode_guarded(node, &data)
    }

    /// The compressed bytes of `node`.
    pub fn read_chunk(&self, read: &dyn ByteSource, node: &Node) -> Result<Vec<u8>, LoadError> {
        read_at(
            &self.file,
            read,
            node.offset,
            node.bytes,
            self.size,
            "the chunk",
        )
    }

    /// [`Self::decode`] on a thread with a deep stack (the LAZ decoder recurses).
    pub fn decode_guarded(&self, node: &Node, data: &[u8]) -> Result<Decoded, LoadError> {
        guard::deep_stack(|| self.decode(node, data))
    }

    /// Decodes one chunk (`data`, the node's bytes) into its points.
    pub fn decode(&self, node: &Node, data: &[u8]) -> Result<Decoded, LoadError> {
        let (file, header, vlr, layer_count) =
            (&self.file, &self.header, &self.vlr, self.layer_count);
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
        let corrupt =
            |e: String| LoadError::at_byte(file, at(0), format!("corrupt LAZ chunk: {e}"));
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
        let mut out = Decoded {
            extra: vec![Vec::with_capacity(node.points as usize); self.extra.len()],
            ..Decoded::default()
        };
        let transforms = header.transforms();
        for record in records.chunks_exact(stride) {
            let raw =
                las::raw::Point::read_from(record, format).map_err(|e| corrupt(e.to_string()))?;
            let p = las::Point::new(raw, transforms);
            out.world.push(DVec3::new(p.x, p.y, p.z));
            if let Some(c) = p.color {
                out.rgb16.push([c.red, c.green, c.blue]);
            }
            for (column, value) in out.standard.iter_mut().zip(super::las::standard_values(&p)) {
                column.push(value);
            }
            out.gps_time.push(p.gps_time.unwrap_or(0.0));
            for (column, field) in out.extra.iter_mut().zip(&self.extra) {
                column.push(field.read(&p.extra_bytes));
            }
        }
        // A chunk the arithmetic decoder accepted can still be garbage: its points must lie
        // in the node's cube (to a quantization step).
        let (lo, hi) = self.info.cube(node.key);
        let t = self.header.transforms();
        let slack = DVec3::new(t.x.scale, t.y.scale, t.z.scale).abs() + (hi - lo) * 1e-6;
        let outside = out
            .world
            .iter()
            .filter(|p| p.is_finite() && !(p.cmpge(lo - slack).all() && p.cmple(hi + slack).all()))
            .count();
        if outside > 0 {
            return Err(LoadError::at_byte(
                file,
                at(0),
                format!(
                    "corrupt chunk: {outside} of its {} points lie outside node {}'s cube",
                    node.points, node.key
                ),
            ));
        }
        Ok(out)
    }
}

/// The user id of the info VLR that pre-1.0 drafts of COPC wrote where COPC 1.0 writes `copc`.
pub const DRAFT_USER_ID: &str = "entwine";

/// What `surfel info` notes about a pre-1.0 COPC draft.
pub const DRAFT_NOTE: &str =
    "not COPC 1.0: a pre-1.0 COPC draft (VLR user id \"entwine\"), read as plain LAZ";

/// Loads a COPC file, reading only the octree levels that fit `budget` points when one is given.
/// A pre-1.0 draft (a VLR with user id [`DRAFT_USER_ID`] and no COPC info VLR) is read whole as
/// the LAZ file it also is, with [`DRAFT_NOTE`] in its `stats.las`.
pub fn load(path: &Path, budget: Option<u64>) -> Result<Cloud, LoadError> {
    let read = FileSource::open(path).map_err(source_error)?;
    let copc = match CopcFile::open(&read) {
        Ok(copc) => copc,
        Err(e) => return load_draft(path, budget).unwrap_or(Err(e)),
    };
    let file = &copc.file;
    let nodes = hierarchy(&copc, &read)?;
    let declared: u64 = nodes.iter().map(|n| n.points).sum();
    if declared != copc.header.number_of_points() {
        return Err(LoadError::whole(
            file,
            format!(
                "the COPC hierarchy holds {declared} points, but the header declares {}",
                copc.header.number_of_points()
            ),
        ));
    }
    let depth = nodes
        .iter()
        .map(|n| n.key.level as usize + 1)
        .max()
        .unwrap_or(0);
    let mut per_level = vec![0u64; depth];
    for n in &nodes {
        per_level[n.key.level as usize] += n.points;
    }
    let levels = Levels {
        read: select_levels(&per_level, budget),
        points: per_level,
    };
    let mut chosen: Vec<Node> = nodes
        .into_iter()
        .filter(|n| (n.key.level as usize) < levels.read)
        .collect();
    chosen.sort_by_key(|n| n.key.level);
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
            .map(|n| read_at(file, &read, n.offset, n.bytes, copc.size, "the chunk"))
            .collect::<Result<Vec<_>, _>>()?;
        let parts = guard::deep_stack(|| {
            batch
                .par_iter()
                .zip(&data)
                .map(|(node, data)| {
                    let part = copc.decode(node, data);
                    progress.advance(node.points as usize);
                    part
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        for part in parts {
            decoded.append(part);
        }
        start = end;
    }
    progress.finish();
    let bounds = decoded.world.iter().fold(Bounds::EMPTY, |mut b, p| {
        b.add(*p);
        b
    });
    let origin = bounds.centre().unwrap_or(DVec3::ZERO);
    let eight_bit = decoded.rgb16.iter().flatten().all(|&c| c <= 255);
    let mut cloud = to_cloud(&copc, decoded, origin, eight_bit);
    cloud.stats = LoadStats {
        records: usize::try_from(copc.header.number_of_points()).unwrap_or(usize::MAX),
        levels: Some(levels),
        las: Some(super::las::summary(&copc.header)),
        file_bounds: bounds.centre().map(|_| [bounds.lo, bounds.hi]),
        gps_time_origin: cloud.stats.gps_time_origin,
        ..LoadStats::default()
    };
    cloud.retain_finite();
    Ok(cloud)
}

/// `path` read as LAZ when it is a pre-1.0 COPC draft (see [`load`]); `None` for any other file.
fn load_draft(path: &Path, budget: Option<u64>) -> Option<Result<Cloud, LoadError>> {
    let file = path.display().to_string();
    let size = usize::try_from(std::fs::metadata(path).ok()?.len()).ok()?;
    let mut read = std::io::BufReader::new(std::fs::File::open(path).ok()?);
    let header = super::las::read_header(&file, &mut read, size).ok()?;
    let vlrs = header.vlrs();
    let draft = vlrs
        .iter()
        .any(|v| v.user_id.trim_end_matches('\0') == DRAFT_USER_ID)
        && !vlrs.iter().any(|v| v.is_copc_info());
    if !draft {
        return None;
    }
    if budget.is_some() {
        return Some(Err(LoadError::whole(
            &file,
            "a pre-1.0 COPC draft (VLR user id \"entwine\") has no COPC 1.0 octree to read by levels; read it whole, without --level-budget",
        )));
    }
    Some(super::las::load(path).map(|mut cloud| {
        if let Some(las) = &mut cloud.stats.las {
            las.note = Some(DRAFT_NOTE.to_owned());
        }
        cloud
    }))
}

/// The cloud of decoded points, relative to `origin`; 16-bit colour channels are scaled to 8
/// bits unless `eight_bit` (files that store 8-bit values in the 16-bit fields). GPS times
/// are relative to the earliest the info VLR records (to the earliest decoded point's when it
/// records no range), so a streamed node's times match the whole file's and a LAS file's
/// converted to it (`stats.gps_time_origin`).
/// Non-finite points are kept (the caller drops them).
pub fn to_cloud(copc: &CopcFile, decoded: Decoded, origin: DVec3, eight_bit: bool) -> Cloud {
    let n = decoded.world.len();
    let colors = (decoded.rgb16.len() == n && n > 0).then(|| {
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
    let (earliest, latest) = copc.info.gps_time;
    let time_origin = if earliest.is_finite() && latest >= earliest {
        earliest
    } else {
        let decoded_earliest = decoded
            .gps_time
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        if decoded_earliest.is_finite() {
            decoded_earliest
        } else {
            0.0
        }
    };
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
                values: decoded
                    .gps_time
                    .iter()
                    .map(|t| (t - time_origin) as f32)
                    .collect(),
            }))
            .chain(
                copc.extra
                    .iter()
                    .zip(decoded.extra)
                    .map(|(f, values)| Scalar {
                        name: f.name.clone(),
                        values,
                    }),
            )
            .collect(),
        origin,
        stats: LoadStats {
            gps_time_origin: Some(time_origin),
            ..LoadStats::default()
        },
        up: super::Up::Z,
        survey: true,
        ..Cloud::default()
    };
    cloud.adopt_geometry_fields();
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

//! Reading and decoding streamed files on a pool of worker threads, off the frame loop.
//!
//! A streamed scene is a forest of files ([`TileId`]s): one COPC file, or the files of a
//! virtual point cloud (`.vpc`, [`super::vpc`]) sharing one local frame (the origin is the
//! centre of every file's bounds, so positions stay precise in single precision). A file of
//! a `.vpc` is opened by a worker the first time a view reaches its bounds ([`Job::Open`]):
//! a COPC file's header, root hierarchy page and root node are read then; a LAS or LAZ file
//! is read whole and drawn as one node. The frame loop hands the loader the files, pages and
//! nodes it wants, most wanted first ([`Loader::request`] replaces whatever has not started
//! yet), and collects what finished ([`Loader::poll`], never blocking). A worker reads a
//! hierarchy page and checks its entries, or reads a node's chunk, decodes it, completes what
//! the file lacks (k-NN normals and radii over the node's own points: a node is a subsample
//! at its level's spacing, so its splats are sized for that level), orders it along a Morton
//! curve, cuts it into batches and encodes every point stream the renderer reads. The result
//! is ready to copy into the GPU pool. Every HTTP file of a scene is read through one
//! [`HttpPool`] (kept-alive connections, a cap on requests in flight).

use std::collections::{HashSet, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use glam::DVec3;

use super::select::Hierarchy;
use super::vpc::{self, Encoding};
use crate::layout::GpuBatch;
use crate::point_streams::{Stream, StreamLayout};
use crate::scene::copc::{self, CopcFile, Entry, Info, Key, Node};
use crate::scene::preprocess::{self, PreprocessOptions};
use crate::scene::{Cloud, LoadError, Scalar};
use crate::source::{self, ByteSource, HttpOptions, HttpPool};

/// How nodes are prepared.
#[derive(Clone, Debug)]
pub struct LoaderOptions {
    /// Worker threads (at least one).
    pub threads: usize,
    /// Neighbours for the normals and radii a file lacks; 0: no normals, radii from the
    /// node's level spacing.
    pub k: usize,
    /// The scalar field uploaded for colouring, by index in a node cloud's scalars.
    pub scalar: Option<usize>,
    /// Fit and stream the splats' linear normal fields (Phong splatting, EWA), per node.
    pub normal_field: bool,
    pub http: HttpOptions,
}

impl Default for LoaderOptions {
    fn default() -> Self {
        Self {
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            k: preprocess::DEFAULT_K,
            scalar: None,
            normal_field: false,
            http: HttpOptions::default(),
        }
    }
}

/// A file of the streamed scene, by its index.
pub type TileId = usize;

/// A decoded node, encoded as point streams.
#[derive(Debug)]
pub struct EncodedNode {
    pub key: Key,
    pub points: u32,
    /// Batch bounds; `first` counts from the node's first point.
    pub batches: Vec<GpuBatch>,
    /// Every stream of [`Loader::streams`] in turn, each `StreamLayout::stream_bytes` long.
    pub data: Vec<u8>,
    /// The node's points per classification class, ascending (`color::legend`; empty without
    /// the field).
    pub classes: Vec<(u32, usize)>,
}

/// A file a worker opened: its hierarchy so far and its root node, encoded.
#[derive(Debug)]
pub struct OpenedTile {
    pub hierarchy: Hierarchy,
    pub root: EncodedNode,
}

/// What a worker finished.
#[derive(Debug)]
pub enum Done {
    Opened {
        tile: TileId,
        result: Result<OpenedTile, LoadError>,
    },
    Page {
        tile: TileId,
        key: Key,
        at: u64,
        entries: Result<Vec<Entry>, LoadError>,
    },
    Node {
        tile: TileId,
        key: Key,
        result: Result<EncodedNode, LoadError>,
    },
}

/// A file a worker opened, before the loader keeps it.
struct Opening {
    file: TileFile,
    opened: OpenedTile,
}

/// What a worker sends.
enum Finished {
    Opened {
        tile: TileId,
        result: Result<Box<Opening>, LoadError>,
    },
    Other(Done),
}

/// Work for a worker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    Open(TileId),
    Page {
        tile: TileId,
        key: Key,
        at: u64,
        len: u64,
    },
    Node(TileId, Node),
}

/// A job's identity: kind (0 open, 1 page, 2 node), file, node.
type JobId = (u8, TileId, Key);

impl Job {
    fn id(&self) -> JobId {
        match self {
            Job::Open(t) => (0, *t, Key::ROOT),
            Job::Page { tile, key, .. } => (1, *tile, *key),
            Job::Node(t, n) => (2, *t, n.key),
        }
    }
}

/// A job with what the worker needs to do it.
enum Work {
    Open(TileId, Spec),
    Page(TileId, Arc<TileFile>, Key, u64, u64),
    Node(TileId, Arc<TileFile>, Node),
}

#[derive(Default)]
struct Queue {
    jobs: VecDeque<Work>,
    closed: bool,
}

/// Work the loader's threads have done, summed over threads.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoaderStats {
    pub nodes: u64,
    pub points: u64,
    /// Seconds reading chunks (file or network).
    pub read_s: f64,
    /// Seconds decompressing LAZ.
    pub decode_s: f64,
    /// Seconds estimating normals and radii, ordering and encoding.
    pub prepare_s: f64,
}

#[derive(Default)]
struct Counters {
    nodes: AtomicU64,
    points: AtomicU64,
    read_ns: AtomicU64,
    decode_ns: AtomicU64,
    prepare_ns: AtomicU64,
}

fn add_since(counter: &AtomicU64, start: Instant) -> Instant {
    let now = Instant::now();
    counter.fetch_add((now - start).as_nanos() as u64, Ordering::Relaxed);
    now
}

/// What the scene knows of a file before opening it.
#[derive(Clone, Debug)]
struct Spec {
    location: String,
    encoding: Encoding,
}

/// An opened file.
pub struct TileFile {
    /// Where it is read.
    spec: Spec,
    /// The COPC file; `None` for a LAS or LAZ file, drawn whole as its root node.
    pub copc: Option<CopcFile>,
    /// The octree's cube (a LAS or LAZ file's: the cube around its bounds).
    pub info: Info,
    /// Where its bytes come from (a COPC file's).
    source: Option<Arc<dyn ByteSource>>,
    /// Bytes and reads of a file read whole.
    whole: (u64, u64),
    /// Whether its colours are 8-bit values in the 16-bit fields (judged on the root).
    eight_bit: bool,
}

impl TileFile {
    /// Bytes read from the file so far.
    pub fn bytes_read(&self) -> u64 {
        self.source
            .as_ref()
            .map_or(self.whole.0, |s| s.bytes_read())
    }

    /// Reads (requests) so far.
    pub fn reads(&self) -> u64 {
        self.source.as_ref().map_or(self.whole.1, |s| s.reads())
    }
}

/// One file of the scene, as the loader tracks it.
pub struct Tile {
    /// The `.vpc`'s href (the location for a single file).
    pub href: String,
    /// Where it is read.
    pub location: String,
    /// Points, as the `.vpc` (or the header) says.
    pub points: u64,
    /// Bounds in file coordinates.
    pub bounds: (DVec3, DVec3),
    encoding: Encoding,
    /// The opened file.
    pub file: Option<Arc<TileFile>>,
    /// Why it could not be opened.
    pub error: Option<String>,
}

impl Tile {
    /// Bytes read from the file so far (0 while it is not opened).
    pub fn bytes_read(&self) -> u64 {
        self.file.as_ref().map_or(0, |f| f.bytes_read())
    }

    /// Reads (requests) so far.
    pub fn reads(&self) -> u64 {
        self.file.as_ref().map_or(0, |f| f.reads())
    }
}

/// What every worker shares.
struct Shared {
    counters: Counters,
    origin: DVec3,
    http: Arc<HttpPool>,
    /// The first file's root's scalar names and colours: every file's nodes are given these.
    scalars: Vec<String>,
    colors: bool,
    has_normals: bool,
    streams: Vec<Stream>,
    options: LoaderOptions,
}

/// The worker pool of one streamed scene.
pub struct Loader {
    shared: Arc<Shared>,
    tiles: Vec<Tile>,
    queue: Arc<(Mutex<Queue>, Condvar)>,
    done: Receiver<Finished>,
    workers: Vec<JoinHandle<()>>,
    /// Jobs queued or running.
    in_flight: HashSet<JobId>,
    /// Files that failed before any frame, reported once by the scene.
    pub failed_at_open: Vec<(TileId, String)>,
}

/// What opening a streamed scene learns before any frame.
pub struct Opened {
    pub loader: Loader,
    /// The file opened first (nearest the scene's centre).
    pub tile: TileId,
    /// Its root page's entries.
    pub hierarchy: Hierarchy,
    /// Its root node, decoded (its attributes stand for the scene's: colour ranges, fields).
    pub root: Cloud,
}

/// A file's failure for a message: "tile HREF skipped: ERROR".
fn tile_message(href: &str, e: &impl std::fmt::Display) -> String {
    format!("tile {href} skipped: {e}")
}

/// A source's failure as a load error on `location` (its message names the location already).
fn source_error(location: &str, e: source::SourceError) -> LoadError {
    let message = e
        .message
        .strip_prefix(location)
        .map_or(e.message.as_str(), |m| {
            m.trim_start_matches(':').trim_start()
        });
    LoadError::whole(location, message)
}

/// Bounds of a file from its header, for a `.vpc` item without a 3D `proj:bbox`.
fn header_bounds(spec: &Spec, http: &Arc<HttpPool>) -> Result<(DVec3, DVec3), LoadError> {
    let header = match spec.encoding {
        Encoding::Copc => {
            let source = source::open_in(&spec.location, http)
                .map_err(|e| source_error(&spec.location, e))?;
            CopcFile::open(source.as_ref())?.header
        }
        _ => {
            let (path, _) = local_copy(spec, http)?;
            let reader = las::Reader::from_path(path.path()).map_err(|e| {
                LoadError::whole(&spec.location, format!("invalid LAS header: {e}"))
            })?;
            reader.header().clone()
        }
    };
    let b = header.bounds();
    Ok((
        DVec3::new(b.min.x, b.min.y, b.min.z),
        DVec3::new(b.max.x, b.max.y, b.max.z),
    ))
}

/// A path to the file: itself, or a temporary copy of a URL's bytes (removed on drop), and
/// the bytes and reads that took.
fn local_copy(spec: &Spec, http: &Arc<HttpPool>) -> Result<(LocalFile, (u64, u64)), LoadError> {
    if !source::is_url(&spec.location) {
        let size = std::fs::metadata(&spec.location).map_or(0, |m| m.len());
        return Ok((LocalFile::Given(spec.location.clone().into()), (size, 1)));
    }
    let source =
        source::open_in(&spec.location, http).map_err(|e| source_error(&spec.location, e))?;
    let bytes = source
        .read_at(0, source.len())
        .map_err(|e| source_error(&spec.location, e))?;
    static COUNT: AtomicU64 = AtomicU64::new(0);
    let name = spec.location.rsplit('/').next().unwrap_or("tile.las");
    let path = std::env::temp_dir().join(format!(
        "surfel-{}-{}-{name}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, &bytes).map_err(|source| LoadError::Io {
        file: path.display().to_string(),
        source,
    })?;
    Ok((
        LocalFile::Temporary(path),
        (source.bytes_read(), source.reads()),
    ))
}

/// A local file to read: given, or a temporary copy removed on drop.
enum LocalFile {
    Given(std::path::PathBuf),
    Temporary(std::path::PathBuf),
}

impl LocalFile {
    fn path(&self) -> &std::path::Path {
        match self {
            LocalFile::Given(p) | LocalFile::Temporary(p) => p,
        }
    }
}

impl Drop for LocalFile {
    fn drop(&mut self) {
        if let LocalFile::Temporary(p) = self {
            // A copy left behind is only a temporary file.
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Opens the file of `spec` in the local frame at `origin` (`None`: the centre of the file's
/// header bounds): the opened file, its root hierarchy page and its root node's points.
fn open_tile(
    spec: &Spec,
    http: &Arc<HttpPool>,
    origin: Option<DVec3>,
) -> Result<(TileFile, Hierarchy, Cloud, DVec3), LoadError> {
    if spec.encoding != Encoding::Copc {
        return open_whole(spec, http, origin);
    }
    let source =
        source::open_in(&spec.location, http).map_err(|e| source_error(&spec.location, e))?;
    let copc = CopcFile::open(source.as_ref())?;
    let mut hierarchy = Hierarchy::default();
    let (at, len) = copc.info.root;
    let entries = copc::read_page(&copc.file, source.as_ref(), at, len, copc.size)?;
    hierarchy.add_page(at, entries);
    let root = *hierarchy.nodes.get(&Key::ROOT).ok_or_else(|| {
        LoadError::whole(
            &copc.file,
            "the COPC hierarchy has no root node with points",
        )
    })?;
    let decoded = copc.read_node(source.as_ref(), &root)?;
    let origin = origin.unwrap_or_else(|| {
        let header = copc.header.bounds();
        let centre = (DVec3::new(header.min.x, header.min.y, header.min.z)
            + DVec3::new(header.max.x, header.max.y, header.max.z))
            * 0.5;
        if centre.is_finite() {
            centre
        } else {
            copc.info.center
        }
    });
    // Files that store 8-bit colours in the 16-bit fields, judged on the root's sample.
    let eight_bit = decoded.rgb16.iter().flatten().all(|&c| c <= 255);
    let mut cloud = copc::to_cloud(&copc, decoded, origin, eight_bit);
    cloud.retain_finite();
    cloud.up = crate::scene::Up::Z;
    let info = copc.info;
    Ok((
        TileFile {
            spec: spec.clone(),
            copc: Some(copc),
            info,
            source: Some(source),
            whole: (0, 0),
            eight_bit,
        },
        hierarchy,
        cloud,
        origin,
    ))
}

/// Opens a LAS or LAZ file: read whole, its points one root node.
fn open_whole(
    spec: &Spec,
    http: &Arc<HttpPool>,
    origin: Option<DVec3>,
) -> Result<(TileFile, Hierarchy, Cloud, DVec3), LoadError> {
    let (path, whole) = local_copy(spec, http)?;
    let mut cloud = crate::scene::las::load(path.path()).map_err(|e| match e {
        LoadError::Parse {
            location, message, ..
        } => LoadError::parse(&spec.location, location, message),
        LoadError::Io { source, .. } => LoadError::Io {
            file: spec.location.clone(),
            source,
        },
        e => e,
    })?;
    cloud.retain_finite();
    let (lo, hi) = cloud
        .bounds()
        .ok_or_else(|| LoadError::whole(&spec.location, "no points with finite coordinates"))?;
    let (lo, hi) = (cloud.origin + lo.as_dvec3(), cloud.origin + hi.as_dvec3());
    let origin = origin.unwrap_or((lo + hi) * 0.5);
    let shift = (cloud.origin - origin).as_vec3();
    for p in &mut cloud.positions {
        *p += shift;
    }
    cloud.origin = origin;
    cloud.up = crate::scene::Up::Z;
    let n = cloud.len() as u64;
    let halfsize = ((hi - lo).max_element() * 0.5).max(f64::MIN_POSITIVE);
    let info = Info {
        center: (lo + hi) * 0.5,
        halfsize,
        spacing: 2.0 * halfsize / (n.max(1) as f64).sqrt(),
        root: (0, 0),
        gps_time: (0.0, 0.0),
    };
    let mut hierarchy = Hierarchy::default();
    hierarchy.add_page(
        0,
        vec![Entry::Node(Node {
            key: Key::ROOT,
            offset: 0,
            bytes: 0,
            points: n,
            entry_at: 0,
        })],
    );
    Ok((
        TileFile {
            spec: spec.clone(),
            copc: None,
            info,
            source: None,
            whole,
            eight_bit: false,
        },
        hierarchy,
        cloud,
        origin,
    ))
}

/// The scene's files: one COPC file, or the items of a `.vpc`; and whether it is a `.vpc`.
fn specs(location: &str, http: &HttpOptions) -> Result<(Vec<Tile>, bool), LoadError> {
    if !vpc::is_vpc(location) {
        let tile = Tile {
            href: location.to_owned(),
            location: location.to_owned(),
            points: 0,
            bounds: (DVec3::ZERO, DVec3::ZERO),
            encoding: Encoding::Copc,
            file: None,
            error: None,
        };
        return Ok((vec![tile], false));
    }
    let parsed =
        vpc::read(location, http).map_err(|e| LoadError::whole(location, format!("{e:#}")))?;
    let tiles = parsed
        .tiles
        .into_iter()
        .map(|t| Tile {
            href: t.href,
            location: t.location,
            points: t.points,
            bounds: t.bounds.map_or((DVec3::NAN, DVec3::NAN), |(lo, hi)| {
                (DVec3::from_array(lo), DVec3::from_array(hi))
            }),
            encoding: t.encoding,
            file: None,
            error: None,
        })
        .collect();
    Ok((tiles, true))
}

impl Loader {
    /// Opens `location` (a path or an HTTP(S) URL of a COPC file or a `.vpc`): a COPC file's
    /// header, root hierarchy page and root node are read here; of a `.vpc`, the `.vpc` and
    /// the file nearest the centre of the files' bounds (and the headers of items without a 3D
    /// `proj:bbox`); the rest by `options.threads` workers as requested.
    pub fn open(location: &str, options: LoaderOptions) -> Result<Opened, LoadError> {
        let http = HttpPool::new(&options.http);
        let (mut tiles, is_vpc) = specs(location, &options.http)?;
        let mut failed_at_open = Vec::new();
        let spec = |t: &Tile| Spec {
            location: t.location.clone(),
            encoding: t.encoding,
        };
        let (origin, first, (file, hierarchy, root)) = if !is_vpc {
            let (file, hierarchy, root, origin) = open_tile(&spec(&tiles[0]), &http, None)?;
            if let Some(copc) = &file.copc {
                let b = copc.header.bounds();
                tiles[0].points = copc.header.number_of_points();
                tiles[0].bounds = (
                    DVec3::new(b.min.x, b.min.y, b.min.z),
                    DVec3::new(b.max.x, b.max.y, b.max.z),
                );
            }
            (origin, 0, (file, hierarchy, root))
        } else {
            for (i, t) in tiles.iter_mut().enumerate() {
                if t.bounds.0.is_nan() {
                    match header_bounds(&spec(t), &http) {
                        Ok(b) => t.bounds = b,
                        Err(e) => {
                            let message = tile_message(&t.href, &e);
                            t.error = Some(message.clone());
                            failed_at_open.push((i, message));
                        }
                    }
                }
            }
            let known = || tiles.iter().filter(|t| t.error.is_none());
            let lo = known().fold(DVec3::INFINITY, |a, t| a.min(t.bounds.0));
            let hi = known().fold(DVec3::NEG_INFINITY, |a, t| a.max(t.bounds.1));
            let origin = (lo + hi) * 0.5;
            let mut order: Vec<usize> = (0..tiles.len())
                .filter(|&i| tiles[i].error.is_none())
                .collect();
            let distance = |t: &Tile| ((t.bounds.0 + t.bounds.1) * 0.5 - origin).length();
            order.sort_by(|&a, &b| distance(&tiles[a]).total_cmp(&distance(&tiles[b])));
            let mut opened = None;
            for i in order {
                match open_tile(&spec(&tiles[i]), &http, Some(origin)) {
                    Ok((file, hierarchy, root, _)) => {
                        opened = Some((i, (file, hierarchy, root)));
                        break;
                    }
                    Err(e) => {
                        let message = tile_message(&tiles[i].href, &e);
                        tiles[i].error = Some(message.clone());
                        failed_at_open.push((i, message));
                    }
                }
            }
            let Some((first, opened)) = opened else {
                let why: Vec<&str> = failed_at_open.iter().map(|(_, m)| m.as_str()).collect();
                return Err(LoadError::whole(
                    location,
                    format!("no tile could be opened: {}", why.join("; ")),
                ));
            };
            (origin, first, opened)
        };
        let probe = Cloud {
            normals: Some(Vec::new()),
            ..root.clone()
        };
        let mut streams = StreamLayout::streams_for(&probe, options.scalar);
        if options.normal_field {
            streams.push(Stream::NormalField);
        }
        // One byte per point for the viewer's class filter.
        if let Some(k) = crate::scene::clip::classification_field(&root) {
            streams.push(Stream::Classes(k));
        }
        let shared = Arc::new(Shared {
            counters: Counters::default(),
            origin,
            http,
            scalars: root.scalars.iter().map(|s| s.name.clone()).collect(),
            colors: root.colors.is_some(),
            has_normals: root.normals.is_some() || options.k > 0,
            streams,
            options: options.clone(),
        });
        tiles[first].file = Some(Arc::new(file));
        let queue = Arc::new((Mutex::new(Queue::default()), Condvar::new()));
        let (send, done) = mpsc::channel();
        let workers = (0..options.threads.max(1))
            .map(|i| {
                let (shared, queue, send) = (shared.clone(), queue.clone(), send.clone());
                std::thread::Builder::new()
                    .name(format!("stream-{i}"))
                    .spawn(move || work(&shared, &queue, &send))
                    .map_err(|e| LoadError::whole(location, format!("cannot start a worker: {e}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Opened {
            loader: Loader {
                shared,
                tiles,
                queue,
                done,
                workers,
                in_flight: HashSet::new(),
                failed_at_open,
            },
            tile: first,
            hierarchy,
            root,
        })
    }

    /// The scene's files.
    pub fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// Bytes read so far over every file.
    pub fn bytes_read(&self) -> u64 {
        self.tiles.iter().map(Tile::bytes_read).sum()
    }

    /// Points of every file.
    pub fn points(&self) -> u64 {
        self.tiles.iter().map(|t| t.points).sum()
    }

    /// The local frame's origin (file coordinates): the centre of the files' bounds.
    pub fn origin(&self) -> DVec3 {
        self.shared.origin
    }

    /// Whether nodes carry normals (the file's, or estimated): without, frames are unlit.
    pub fn has_normals(&self) -> bool {
        self.shared.has_normals
    }

    /// Whether the nodes carry colours.
    pub fn has_colors(&self) -> bool {
        self.shared.colors
    }

    /// The files' bounds in the local frame (minus [`Self::origin`]).
    pub fn local_bounds(&self) -> (glam::Vec3, glam::Vec3) {
        let known = || self.tiles.iter().filter(|t| t.error.is_none());
        let lo = known().fold(DVec3::INFINITY, |a, t| a.min(t.bounds.0));
        let hi = known().fold(DVec3::NEG_INFINITY, |a, t| a.max(t.bounds.1));
        let o = self.shared.origin;
        ((lo - o).as_vec3(), (hi - o).as_vec3())
    }

    /// The streams every node is encoded into.
    pub fn streams(&self) -> &[Stream] {
        &self.shared.streams
    }

    /// Encodes node `key` of file `tile`, decoded elsewhere (the root, read at open), as the
    /// workers do.
    pub fn encode(&self, tile: TileId, key: Key, cloud: Cloud) -> Result<EncodedNode, LoadError> {
        let file = self.tiles[tile]
            .file
            .as_ref()
            .ok_or_else(|| LoadError::whole(&self.tiles[tile].location, "the file is not open"))?;
        encode(&self.shared, file, &self.tiles[tile].location, key, cloud)
    }

    /// Reads and decodes `nodes` (file, node) again, in parallel on the calling thread's
    /// pool, as the scene's points (their fields conformed, no normals or radii added): for
    /// tools that need drawn nodes' points on the CPU, which the workers do not keep once
    /// encoded.
    pub fn read_points(&self, nodes: &[(TileId, Node)]) -> Vec<Result<Cloud, LoadError>> {
        use rayon::prelude::*;
        let (shared, tiles) = (&*self.shared, &self.tiles);
        nodes
            .par_iter()
            .map(|(tile, node)| {
                let t = &tiles[*tile];
                let file = t
                    .file
                    .as_ref()
                    .ok_or_else(|| LoadError::whole(&t.location, "the file is not open"))?;
                let mut cloud = match (&file.copc, &file.source) {
                    (Some(copc), Some(source)) => {
                        let data = copc.read_chunk(source.as_ref(), node)?;
                        let decoded = copc.decode_guarded(node, &data)?;
                        let mut cloud =
                            copc::to_cloud(copc, decoded, shared.origin, file.eight_bit);
                        cloud.retain_finite();
                        cloud
                    }
                    _ => open_whole(&file.spec, &shared.http, Some(shared.origin))?.2,
                };
                conform(shared, &mut cloud);
                Ok(cloud)
            })
            .collect()
    }

    /// What the workers have done so far.
    pub fn stats(&self) -> LoaderStats {
        let c = &self.shared.counters;
        let s = |n: &AtomicU64| n.load(Ordering::Relaxed) as f64 * 1e-9;
        LoaderStats {
            nodes: c.nodes.load(Ordering::Relaxed),
            points: c.points.load(Ordering::Relaxed),
            read_s: s(&c.read_ns),
            decode_s: s(&c.decode_ns),
            prepare_s: s(&c.prepare_ns),
        }
    }

    /// Jobs queued or running.
    pub fn pending(&self) -> usize {
        self.in_flight.len()
    }

    /// Replaces the jobs not started yet by `jobs` (most wanted first); a job already running
    /// is not queued again, nor one on a file that failed or is not open.
    pub fn request(&mut self, jobs: &[Job]) {
        let (lock, wake) = &*self.queue;
        let mut queue = lock.lock().unwrap_or_else(|e| e.into_inner());
        for dropped in queue.jobs.drain(..) {
            let id = match dropped {
                Work::Open(t, _) => (0, t, Key::ROOT),
                Work::Page(t, _, key, _, _) => (1, t, key),
                Work::Node(t, _, n) => (2, t, n.key),
            };
            self.in_flight.remove(&id);
        }
        for job in jobs {
            let tile = &self.tiles[job.id().1];
            if tile.error.is_some() {
                continue;
            }
            let work = match (*job, &tile.file) {
                (Job::Open(t), None) => Work::Open(
                    t,
                    Spec {
                        location: tile.location.clone(),
                        encoding: tile.encoding,
                    },
                ),
                (Job::Page { tile, key, at, len }, Some(f)) => {
                    Work::Page(tile, f.clone(), key, at, len)
                }
                (Job::Node(t, n), Some(f)) => Work::Node(t, f.clone(), n),
                _ => continue,
            };
            if self.in_flight.insert(job.id()) {
                queue.jobs.push_back(work);
            }
        }
        wake.notify_all();
    }

    /// What finished since the last call (never waits).
    pub fn poll(&mut self) -> Vec<Done> {
        let done: Vec<Finished> = self.done.try_iter().collect();
        self.finished(done)
    }

    /// Forgets the jobs of `done` as in flight and keeps the files opened.
    fn finished(&mut self, done: Vec<Finished>) -> Vec<Done> {
        done.into_iter()
            .map(|d| match d {
                Finished::Opened { tile, result } => {
                    self.in_flight.remove(&(0, tile, Key::ROOT));
                    let result = match result {
                        Ok(opening) => {
                            let Opening { file, opened } = *opening;
                            self.tiles[tile].file = Some(Arc::new(file));
                            Ok(opened)
                        }
                        Err(e) => {
                            let t = &mut self.tiles[tile];
                            t.error = Some(tile_message(&t.href, &e));
                            Err(e)
                        }
                    };
                    Done::Opened { tile, result }
                }
                Finished::Other(d) => {
                    let id = match &d {
                        Done::Opened { tile, .. } => (0, *tile, Key::ROOT),
                        Done::Page { tile, key, .. } => (1, *tile, *key),
                        Done::Node { tile, key, .. } => (2, *tile, *key),
                    };
                    self.in_flight.remove(&id);
                    d
                }
            })
            .collect()
    }

    /// Waits for the next finished job (for a headless renderer with nothing else to do).
    pub fn wait(&mut self, timeout: std::time::Duration) -> Vec<Done> {
        match self.done.recv_timeout(timeout) {
            Ok(first) => {
                let mut done = vec![first];
                done.extend(self.done.try_iter());
                self.finished(done)
            }
            Err(_) => Vec::new(),
        }
    }
}
impl Drop for Loader {
    fn drop(&mut self) {
        let (lock, wake) = &*self.queue;
        {
            let mut queue = lock.lock().unwrap_or_else(|e| e.into_inner());
            queue.closed = true;
            queue.jobs.clear();
        }
        wake.notify_all();
        for w in self.workers.drain(..) {
            // A worker that panicked has nothing left to clean up.
            let _ = w.join();
        }
    }
}

fn work(shared: &Shared, queue: &(Mutex<Queue>, Condvar), send: &Sender<Finished>) {
    let (lock, wake) = queue;
    loop {
        let job = {
            let mut q = lock.lock().unwrap_or_else(|e| e.into_inner());
            loop {
                if q.closed {
                    return;
                }
                if let Some(job) = q.jobs.pop_front() {
                    break job;
                }
                q = wake.wait(q).unwrap_or_else(|e| e.into_inner());
            }
        };
        let done = match job {
            Work::Open(tile, spec) => Finished::Opened {
                tile,
                result: open_job(shared, &spec),
            },
            Work::Page(tile, file, key, at, len) => Finished::Other(Done::Page {
                tile,
                key,
                at,
                entries: match (&file.copc, &file.source) {
                    (Some(copc), Some(source)) => {
                        copc::read_page(&copc.file, source.as_ref(), at, len, copc.size)
                    }
                    _ => Ok(Vec::new()),
                },
            }),
            Work::Node(tile, file, node) => Finished::Other(Done::Node {
                tile,
                key: node.key,
                result: load_node(shared, &file, &node),
            }),
        };
        if send.send(done).is_err() {
            return;
        }
    }
}

/// Opens a file in the scene's frame and encodes its root.
/// Its reading and decoding count as reading.
fn open_job(shared: &Shared, spec: &Spec) -> Result<Box<Opening>, LoadError> {
    let c = &shared.counters;
    let start = Instant::now();
    let (file, hierarchy, cloud, _) = open_tile(spec, &shared.http, Some(shared.origin))?;
    let start = add_since(&c.read_ns, start);
    let points = cloud.len() as u64;
    let root = encode(shared, &file, &spec.location, Key::ROOT, cloud)?;
    add_since(&c.prepare_ns, start);
    c.nodes.fetch_add(1, Ordering::Relaxed);
    c.points.fetch_add(points, Ordering::Relaxed);
    Ok(Box::new(Opening {
        file,
        opened: OpenedTile { hierarchy, root },
    }))
}

/// Reads, decodes and encodes `node`, counting the time of each step.
fn load_node(shared: &Shared, file: &TileFile, node: &Node) -> Result<EncodedNode, LoadError> {
    let (Some(copc), Some(source)) = (&file.copc, &file.source) else {
        // A file read whole, read again (its root was evicted).
        let (_, _, cloud, _) = open_whole(&file.spec, &shared.http, Some(shared.origin))?;
        return encode(shared, file, &file.spec.location, node.key, cloud);
    };
    let c = &shared.counters;
    let start = Instant::now();
    let data = copc.read_chunk(source.as_ref(), node)?;
    let start = add_since(&c.read_ns, start);
    let decoded = copc.decode_guarded(node, &data)?;
    let start = add_since(&c.decode_ns, start);
    let mut cloud = copc::to_cloud(copc, decoded, shared.origin, file.eight_bit);
    cloud.retain_finite();
    let encoded = encode(shared, file, &copc.file, node.key, cloud)?;
    add_since(&c.prepare_ns, start);
    c.nodes.fetch_add(1, Ordering::Relaxed);
    c.points.fetch_add(node.points, Ordering::Relaxed);
    Ok(encoded)
}

/// `cloud` with the scene's scalar fields in the scene's order (a field the file lacks is
/// zero, one the scene lacks dropped) and colours when the scene has them (white where the
/// file has none).
fn conform(shared: &Shared, cloud: &mut Cloud) {
    if cloud
        .scalars
        .iter()
        .map(|s| &s.name)
        .eq(shared.scalars.iter())
    {
        return;
    }
    let n = cloud.len();
    let mut old = std::mem::take(&mut cloud.scalars);
    cloud.scalars = shared
        .scalars
        .iter()
        .map(|name| match old.iter().position(|s| &s.name == name) {
            Some(i) => old.swap_remove(i),
            None => Scalar {
                name: name.clone(),
                values: vec![0.0; n],
            },
        })
        .collect();
    match (shared.colors, cloud.colors.is_some()) {
        (true, false) => cloud.colors = Some(vec![[255; 4]; n]),
        (false, true) => cloud.colors = None,
        _ => {}
    }
}

/// Completes and encodes the points of node `key` of `file` (named `name` in errors).
fn encode(
    shared: &Shared,
    file: &TileFile,
    name: &str,
    key: Key,
    mut cloud: Cloud,
) -> Result<EncodedNode, LoadError> {
    conform(shared, &mut cloud);
    let n = cloud.len();
    if shared.options.k > 0 && n > 0 {
        preprocess::preprocess(
            &mut cloud,
            &PreprocessOptions {
                k: shared.options.k.min(n.saturating_sub(1)).max(1),
                progress: false,
                ..PreprocessOptions::default()
            },
        );
    }
    if cloud.radii.is_none() {
        let node = Node {
            key,
            offset: 0,
            bytes: 0,
            points: n as u64,
            entry_at: 0,
        };
        let spacing = super::select::spacing(&file.info, &node);
        cloud.radii = Some(vec![spacing as f32; n]);
    }
    if cloud.normals.is_none() {
        // No normals to light with: the renderer shows such a file unlit.
        cloud.normals = Some(vec![glam::Vec3::Z; n]);
    }
    let mut layout = StreamLayout::new(&cloud, u64::MAX, shared.options.scalar)
        .map_err(|e| LoadError::whole(name, e))?;
    if shared.options.normal_field {
        layout = layout.with_normal_field(crate::scene::normal_field::fit_cloud(&cloud));
    }
    if let Some(classes) = shared
        .streams
        .iter()
        .find(|s| matches!(s, Stream::Classes(_)))
    {
        layout.streams.push(*classes);
    }
    if layout.streams != shared.streams {
        return Err(LoadError::whole(
            name,
            format!("node {key}: its fields differ from the root node's"),
        ));
    }
    let bytes: u64 = layout
        .streams
        .iter()
        .map(|s| StreamLayout::stream_bytes(*s, n as u64))
        .sum();
    let mut data = vec![0u8; bytes as usize];
    if n > 0 {
        layout.encode_chunk(&cloud, 0..n as u64, &mut data);
    }
    let classes = crate::color::legend(&cloud)
        .into_iter()
        .map(|e| (e.class, e.count))
        .collect();
    Ok(EncodedNode {
        key,
        points: n as u32,
        batches: layout.batches,
        data,
        classes,
    })
}

//! Reading and decoding a streamed COPC file on a pool of worker threads, off the frame loop.
//!
//! The frame loop hands the loader the pages and nodes it wants, most wanted first
//! ([`Loader::request`] replaces whatever has not started yet), and collects what finished
//! ([`Loader::poll`], never blocking). A worker reads a hierarchy page and checks its entries,
//! or reads a node's chunk, decodes it, completes what the file lacks (k-NN normals and radii
//! over the node's own points: a node is a subsample at its level's spacing, so its splats
//! are sized for that level), orders it along a Morton curve, cuts it into batches and encodes
//! every point stream the renderer reads. The result is ready to copy into the GPU pool.

use std::collections::{HashSet, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use glam::DVec3;

use super::select::Hierarchy;
use super::source::{self, ByteSource, HttpOptions};
use crate::gpu::layout::GpuBatch;
use crate::scene::copc::{self, CopcFile, Entry, Key, Node};
use crate::scene::preprocess::{self, PreprocessOptions};
use crate::scene::{Cloud, LoadError};
use crate::streams::{Stream, StreamLayout};

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

/// What a worker finished.
#[derive(Debug)]
pub enum Done {
    Page {
        key: Key,
        at: u64,
        entries: Result<Vec<Entry>, LoadError>,
    },
    Node {
        key: Key,
        result: Result<EncodedNode, LoadError>,
    },
}

/// Work for a worker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    Page { key: Key, at: u64, len: u64 },
    Node(Node),
}

impl Job {
    fn id(&self) -> (bool, Key) {
        match self {
            Job::Page { key, .. } => (true, *key),
            Job::Node(n) => (false, n.key),
        }
    }
}

#[derive(Default)]
struct Queue {
    jobs: VecDeque<Job>,
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

/// What every worker shares.
struct Shared {
    counters: Counters,
    copc: CopcFile,
    source: Arc<dyn ByteSource>,
    origin: DVec3,
    eight_bit: bool,
    has_normals: bool,
    streams: Vec<Stream>,
    options: LoaderOptions,
}

/// The worker pool of one streamed file.
pub struct Loader {
    shared: Arc<Shared>,
    queue: Arc<(Mutex<Queue>, Condvar)>,
    done: Receiver<Done>,
    workers: Vec<JoinHandle<()>>,
    /// Jobs queued or running.
    in_flight: HashSet<(bool, Key)>,
}

/// What opening a streamed file learns before any frame.
pub struct Opened {
    pub loader: Loader,
    /// The root page's entries.
    pub hierarchy: Hierarchy,
    /// The root node, decoded (its attributes stand for the file's: colour ranges, fields).
    pub root: Cloud,
}

impl Loader {
    /// Opens `location` (a path or an HTTP(S) URL): header, root hierarchy page and root node
    /// are read here; the rest by `options.threads` workers as requested.
    pub fn open(location: &str, options: LoaderOptions) -> Result<Opened, LoadError> {
        let source = source::open(location, &options.http)
            .map_err(|e| LoadError::whole(location, e.message))?;
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
        let header = copc.header.bounds();
        let origin = (DVec3::new(header.min.x, header.min.y, header.min.z)
            + DVec3::new(header.max.x, header.max.y, header.max.z))
            * 0.5;
        let origin = if origin.is_finite() {
            origin
        } else {
            copc.info.center
        };
        // Files that store 8-bit colours in the 16-bit fields, judged on the root's sample.
        let eight_bit = decoded.rgb16.iter().flatten().all(|&c| c <= 255);
        let mut root_cloud = copc::to_cloud(&copc, decoded, origin, eight_bit);
        root_cloud.retain_finite();
        root_cloud.up = crate::scene::Up::Z;
        let probe = Cloud {
            normals: Some(Vec::new()),
            ..root_cloud.clone()
        };
        let mut streams = StreamLayout::streams_for(&probe, options.scalar);
        if options.normal_field {
            streams.push(Stream::NormalField);
        }
        // One byte per point for the viewer's class filter.
        if let Some(k) = crate::scene::clip::classification_field(&root_cloud) {
            streams.push(Stream::Classes(k));
        }
        let shared = Arc::new(Shared {
            counters: Counters::default(),
            copc,
            source,
            origin,
            eight_bit,
            has_normals: root_cloud.normals.is_some() || options.k > 0,
            streams,
            options: options.clone(),
        });
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
                queue,
                done,
                workers,
                in_flight: HashSet::new(),
            },
            hierarchy,
            root: root_cloud,
        })
    }

    /// The opened file.
    pub fn copc(&self) -> &CopcFile {
        &self.shared.copc
    }

    /// The file's bytes.
    pub fn source(&self) -> &Arc<dyn ByteSource> {
        &self.shared.source
    }

    /// The local frame's origin (file coordinates): the header's bounding-box centre.
    pub fn origin(&self) -> DVec3 {
        self.shared.origin
    }

    /// Whether nodes carry normals (the file's, or estimated): without, frames are unlit.
    pub fn has_normals(&self) -> bool {
        self.shared.has_normals
    }

    /// The header's bounds in the local frame (minus [`Self::origin`]).
    pub fn local_bounds(&self) -> (glam::Vec3, glam::Vec3) {
        let b = self.shared.copc.header.bounds();
        let o = self.shared.origin;
        (
            (DVec3::new(b.min.x, b.min.y, b.min.z) - o).as_vec3(),
            (DVec3::new(b.max.x, b.max.y, b.max.z) - o).as_vec3(),
        )
    }

    /// The streams every node is encoded into.
    pub fn streams(&self) -> &[Stream] {
        &self.shared.streams
    }

    /// Encodes a node decoded elsewhere (the root, read at open) as the workers do.
    pub fn encode(&self, key: Key, cloud: Cloud) -> Result<EncodedNode, LoadError> {
        encode(&self.shared, key, cloud)
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
    /// is not queued again.
    pub fn request(&mut self, jobs: &[Job]) {
        let (lock, wake) = &*self.queue;
        let mut queue = lock.lock().unwrap_or_else(|e| e.into_inner());
        for dropped in queue.jobs.drain(..) {
            self.in_flight.remove(&dropped.id());
        }
        for job in jobs {
            if self.in_flight.insert(job.id()) {
                queue.jobs.push_back(*job);
            }
        }
        wake.notify_all();
    }

    /// What finished since the last call (never waits).
    pub fn poll(&mut self) -> Vec<Done> {
        let done: Vec<Done> = self.done.try_iter().collect();
        self.finished(&done);
        done
    }

    /// Forgets the jobs of `done` as in flight.
    fn finished(&mut self, done: &[Done]) {
        for d in done {
            let id = match d {
                Done::Page { key, .. } => (true, *key),
                Done::Node { key, .. } => (false, *key),
            };
            self.in_flight.remove(&id);
        }
    }

    /// Waits for the next finished job (for a headless renderer with nothing else to do).
    pub fn wait(&mut self, timeout: std::time::Duration) -> Vec<Done> {
        match self.done.recv_timeout(timeout) {
            Ok(first) => {
                let mut done = vec![first];
                done.extend(self.done.try_iter());
                self.finished(&done);
                done
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

fn work(shared: &Shared, queue: &(Mutex<Queue>, Condvar), send: &Sender<Done>) {
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
            Job::Page { key, at, len } => Done::Page {
                key,
                at,
                entries: copc::read_page(
                    &shared.copc.file,
                    shared.source.as_ref(),
                    at,
                    len,
                    shared.copc.size,
                ),
            },
            Job::Node(node) => Done::Node {
                key: node.key,
                result: load_node(shared, &node),
            },
        };
        if send.send(done).is_err() {
            return;
        }
    }
}

/// Reads, decodes and encodes `node`, counting the time of each step.
fn load_node(shared: &Shared, node: &Node) -> Result<EncodedNode, LoadError> {
    let c = &shared.counters;
    let start = Instant::now();
    let data = shared.copc.read_chunk(shared.source.as_ref(), node)?;
    let start = add_since(&c.read_ns, start);
    let decoded = shared.copc.decode_guarded(node, &data)?;
    let start = add_since(&c.decode_ns, start);
    let mut cloud = copc::to_cloud(&shared.copc, decoded, shared.origin, shared.eight_bit);
    cloud.retain_finite();
    let encoded = encode(shared, node.key, cloud)?;
    add_since(&c.prepare_ns, start);
    c.nodes.fetch_add(1, Ordering::Relaxed);
    c.points.fetch_add(node.points, Ordering::Relaxed);
    Ok(encoded)
}

/// Completes and encodes the points of node `key`.
fn encode(shared: &Shared, key: Key, mut cloud: Cloud) -> Result<EncodedNode, LoadError> {
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
        let spacing = super::select::spacing(&shared.copc.info, &node);
        cloud.radii = Some(vec![spacing as f32; n]);
    }
    if cloud.normals.is_none() {
        // No normals to light with: the renderer shows such a file unlit.
        cloud.normals = Some(vec![glam::Vec3::Z; n]);
    }
    let mut layout = StreamLayout::new(&cloud, u64::MAX, shared.options.scalar)
        .map_err(|e| LoadError::whole(&shared.copc.file, e))?;
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
            &shared.copc.file,
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

//! A streamed COPC cloud or virtual point cloud on the GPU: a fixed pool of batch slots that the nodes a view needs
//! are copied into, and the per-frame batch table that says which slots to draw.
//!
//! Each frame ([`StreamedScene::update`]): collect what the loader's workers finished (never
//! waiting), choose the nodes of the view within the point budget and the pool
//! (`stream::select`, over every file's octree at once), copy finished nodes of that choice into free slots through the staging
//! ring, evicting the least recently drawn nodes the view does not need, hand the loader the
//! missing nodes and pages most wanted first, and write the table: a chosen node's batches
//! are drawn once it is resident, so a parent stays on screen while its children load. A slot
//! freed by eviction is reused only after every frame in flight that could draw it has
//! finished. A node or page that cannot be read or decoded is reported once and skipped, and
//! so is a file of a virtual point cloud that cannot be opened; rendering goes on with the
//! rest.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap, HashSet, VecDeque};
use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;
use glam::Vec3;

use super::{GpuScene, SceneInfo};
use crate::color::{self, Coloring, LegendEntry};
use crate::copc::loader::{Done, EncodedNode, Job, Loader, LoaderOptions, LoaderStats, TileId};
use crate::copc::select::{self, Budget, ForestSelection, Hierarchy, SelectView, Tree};
use crate::gpu::staging::{CopyRegion, Uploader};
use crate::gpu::Context;
use crate::layout::{GpuBatch, BATCH_POINTS, COLOR_ELEVATION};
use crate::point_streams::upload::pool;
use crate::point_streams::{Stream, StreamLayout};
use crate::scene::copc::Key;
use crate::scene::{Camera, Cloud, Up};

/// Default point budget (Potree's default is 1 M; its interface goes to 10 M).
pub const DEFAULT_POINT_BUDGET: u64 = 2_000_000;

/// Default GPU memory budget of the pool, in bytes.
pub const DEFAULT_GPU_BYTES: u64 = 1 << 30;

/// Default screen-space error: nodes are refined while their spacing exceeds this many pixels
/// (half a pixel: a random subsample at one point per pixel leaves visible holes).
pub const DEFAULT_ERROR_PX: f32 = 0.5;

/// The hierarchy of a file that could not be opened.
static EMPTY: std::sync::LazyLock<Hierarchy> = std::sync::LazyLock::new(Hierarchy::default);

/// Staging bytes per copy (a node larger than this is reported and skipped).
const STAGING_BYTES: u64 = 64 << 20;

/// Most bytes copied into the pool per frame, so a frame's upload stays short.
const UPLOAD_BYTES_PER_FRAME: u64 = 128 << 20;

/// How a cloud is streamed.
#[derive(Clone, Debug)]
pub struct StreamOptions {
    /// Points drawn per frame at most.
    pub point_budget: u64,
    /// Bytes of GPU memory the pool's streams may take.
    pub gpu_bytes: u64,
    /// Screen-space error in pixels.
    pub error_px: f32,
    pub loader: LoaderOptions,
}

impl Default for StreamOptions {
    fn default() -> Self {
        Self {
            point_budget: DEFAULT_POINT_BUDGET,
            gpu_bytes: DEFAULT_GPU_BYTES,
            error_px: DEFAULT_ERROR_PX,
            loader: LoaderOptions::default(),
        }
    }
}

/// A node of the scene: its file and its key in the file's octree.
pub type NodeId = (TileId, Key);

/// A resident node: its slots and batches (`first` at its slot).
struct Resident {
    slots: Vec<u32>,
    batches: Vec<GpuBatch>,
    last_drawn: u64,
}

/// What the streamer is doing, for the viewer's HUD and reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StreamStats {
    /// Points in the view's chosen nodes.
    pub selected_points: u64,
    /// Of those, resident (drawn this frame).
    pub drawn_points: u64,
    pub selected_nodes: usize,
    pub resident_nodes: usize,
    /// Jobs queued or running in the loader.
    pub loading: usize,
    /// Bytes read from the file or server so far.
    pub bytes_read: u64,
    /// Batch slots of the pool, and those holding a node.
    pub slots: u32,
    pub used_slots: u32,
    /// Nodes and pages skipped after an error.
    pub failed: usize,
    /// Nodes evicted so far.
    pub evicted: u64,
    /// Files opened, and in the scene (1 for a COPC file).
    pub tiles_open: usize,
    pub tiles: usize,
    /// The loader's work so far.
    pub loader: LoaderStats,
}

/// A streamed cloud: the loader, what is known of the octree and the GPU pool.
pub struct StreamedScene {
    pub scene: GpuScene,
    pub info: SceneInfo,
    /// The root node (its attributes stand for the file's).
    pub root: Cloud,
    loader: Loader,
    /// Each file's hierarchy, once opened.
    hierarchies: Vec<Option<Hierarchy>>,
    options: StreamOptions,
    uploader: Uploader,
    /// The pool's stream buffers, in the loader's stream order.
    targets: Vec<(Stream, vk::Buffer)>,
    /// Free slots, lowest first (so draws of every index stay short).
    free: BinaryHeap<Reverse<u32>>,
    /// Slots freed at a frame, reusable once the frames in flight then have finished.
    retiring: VecDeque<(u64, Vec<u32>)>,
    frames_in_flight: u64,
    resident: HashMap<NodeId, Resident>,
    /// Decoded nodes waiting for slots.
    ready: HashMap<NodeId, EncodedNode>,
    failed: HashMap<NodeId, String>,
    failed_pages: HashMap<NodeId, String>,
    /// Files that could not be opened.
    failed_tiles: HashSet<TileId>,
    /// Messages not yet taken by [`Self::take_messages`].
    messages: Vec<String>,
    selection: ForestSelection,
    table: Vec<GpuBatch>,
    frame: u64,
    evicted: u64,
    /// The point budget was found below the root node's points (warned once).
    budget_warned: bool,
    /// Points per classification class of the nodes placed so far, each node counted once.
    classes: BTreeMap<u32, usize>,
    counted: HashSet<NodeId>,
}

impl StreamedScene {
    /// Opens `location` (a COPC file's or `.vpc`'s path or URL) and allocates a pool of `options.gpu_bytes`;
    /// `coloring` picks the colour mode (`color::select` on [`Opened::root`]); `frames` is
    /// the renderer's frames in flight.
    pub fn open(
        ctx: &Arc<Context>,
        location: &str,
        options: &StreamOptions,
        coloring: impl FnOnce(&Cloud) -> Result<Coloring>,
        frames: usize,
    ) -> Result<Self> {
        let probe = crate::copc::loader::Loader::open(location, options.loader.clone())?;
        let coloring = coloring(&probe.root)?;
        // The scalar a colour mode reads decides the streams: reopen when it is not the default.
        let opened = if coloring.scalar == options.loader.scalar {
            probe
        } else {
            drop(probe);
            let loader = LoaderOptions {
                scalar: coloring.scalar,
                ..options.loader.clone()
            };
            Loader::open(location, loader)?
        };
        let loader = opened.loader;
        let per_point: u64 = loader.streams().iter().map(|s| s.bytes_per_point()).sum();
        let batch_bytes = per_point * u64::from(BATCH_POINTS);
        let slots = (options.gpu_bytes / batch_bytes).min(u64::from(u32::MAX / BATCH_POINTS));
        let need = select::slots_of(opened.root.len() as u64);
        if slots < need.max(1) {
            bail!(
                "a GPU budget of {} bytes holds {slots} batches of {BATCH_POINTS} points ({batch_bytes} bytes each); the root node alone needs {need}",
                options.gpu_bytes
            );
        }
        let streams = pool(ctx, loader.streams(), slots as u32)?;
        let targets = streams.segments[0]
            .iter()
            .map(|(s, b)| (*s, b.raw))
            .collect();
        let table = streams.host_batches.clone();
        let (lo, hi) = loader.local_bounds();
        let mut coloring = coloring;
        if coloring.mode == COLOR_ELEVATION {
            // The header's bounds, not the root's sample, span the elevations.
            let corners = (0..8).map(|k| {
                let c = Vec3::new(
                    if k & 1 != 0 { hi.x } else { lo.x },
                    if k & 2 != 0 { hi.y } else { lo.y },
                    if k & 4 != 0 { hi.z } else { lo.z },
                );
                c.dot(coloring.axis)
            });
            let (a, b) = corners.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            if a < b {
                coloring.range = [a, b];
            }
        }
        let info = SceneInfo {
            centre: (lo + hi) * 0.5,
            radius: ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE),
            points: streams.point_count,
            has_colors: loader.has_colors(),
            has_normals: loader.has_normals(),
            up: Up::Z,
            origin: loader.origin(),
            coloring,
        };
        let point_count = streams.point_count;
        let scene = GpuScene {
            streams,
            indices: None,
            face_vertices: None,
            ribbons: None,
            tubes: None,
            point_count,
            index_count: 0,
            lod: None,
            hpr: None,
            streamed: true,
            draw_points: super::DrawCount::new(0),
        };
        let mut hierarchies: Vec<Option<Hierarchy>> =
            (0..loader.tiles().len()).map(|_| None).collect();
        hierarchies[opened.tile] = Some(opened.hierarchy);
        let failed_tiles = loader.failed_at_open.iter().map(|(t, _)| *t).collect();
        let messages = loader
            .failed_at_open
            .iter()
            .map(|(_, m)| m.clone())
            .collect();
        let mut out = Self {
            scene,
            info,
            root: opened.root.clone(),
            loader,
            hierarchies,
            options: options.clone(),
            uploader: Uploader::new(ctx, STAGING_BYTES)?,
            targets,
            free: (0..slots as u32).map(Reverse).collect(),
            retiring: VecDeque::new(),
            frames_in_flight: frames.max(1) as u64,
            resident: HashMap::new(),
            ready: HashMap::new(),
            failed: HashMap::new(),
            failed_pages: HashMap::new(),
            failed_tiles,
            messages,
            selection: ForestSelection::default(),
            table,
            frame: 0,
            evicted: 0,
            budget_warned: false,
            classes: BTreeMap::new(),
            counted: HashSet::new(),
        };
        out.check_budget();
        // The root is resident before the first frame.
        let root = out.loader.encode(opened.tile, Key::ROOT, opened.root)?;
        out.ready.insert((opened.tile, Key::ROOT), root);
        let mut budget = UPLOAD_BYTES_PER_FRAME;
        out.place((opened.tile, Key::ROOT), &mut budget)?;
        out.uploader.finish()?;
        Ok(out)
    }

    /// The points' local frame's origin in file coordinates.
    pub fn origin(&self) -> glam::DVec3 {
        self.loader.origin()
    }

    /// The point budget.
    pub fn point_budget(&self) -> u64 {
        self.options.point_budget
    }

    /// Changes the point budget from the next update on.
    pub fn set_point_budget(&mut self, points: u64) {
        self.options.point_budget = points;
        self.check_budget();
    }

    /// The classes of the nodes loaded so far with their points (every node once, also
    /// after it was evicted), for the HUD's legend: it grows as nodes arrive.
    pub fn legend(&self) -> Vec<LegendEntry> {
        self.classes
            .iter()
            .map(|(&class, &count)| color::legend_entry(class, count))
            .collect()
    }

    /// How many classes [`Self::legend`] lists.
    pub fn legend_classes(&self) -> usize {
        self.classes.len()
    }

    /// Points of the root node of a single file (drawn whatever the point budget); 0 for a
    /// virtual point cloud (its files' roots are drawn within the budget).
    pub fn root_points(&self) -> u64 {
        match self.hierarchies.as_slice() {
            [Some(h)] => h.nodes.get(&Key::ROOT).map_or(0, |n| n.points),
            _ => 0,
        }
    }

    /// The streamed files.
    pub fn tiles(&self) -> &[crate::copc::loader::Tile] {
        self.loader.tiles()
    }

    /// The points of chosen node `id`.
    fn node_points(&self, id: &NodeId) -> u64 {
        self.hierarchies[id.0]
            .as_ref()
            .and_then(|h| h.nodes.get(&id.1))
            .map_or(0, |n| n.points)
    }

    /// A point budget below the root node's points still draws the root: says so once.
    fn check_budget(&mut self) {
        let root = self.root_points();
        if self.options.point_budget < root && !self.budget_warned {
            self.budget_warned = true;
            self.messages.push(format!(
                "the point budget {} is below the root node's {root} points; drawing the root",
                self.options.point_budget
            ));
        }
    }

    /// Points in the file (every file of a virtual point cloud, as its `.vpc` says).
    pub fn file_points(&self) -> u64 {
        self.loader.points()
    }

    /// Bytes of the pool's stream buffers (what the GPU budget bounds).
    pub fn pool_bytes(&self) -> u64 {
        let capacity = u64::from(self.scene.streams.point_count);
        self.targets
            .iter()
            .map(|(s, _)| StreamLayout::stream_bytes(*s, capacity))
            .sum()
    }

    /// This frame's batch table (for `Renderer::set_batches`).
    pub fn batches(&self) -> &[GpuBatch] {
        &self.table
    }

    /// Error messages since the last call, each node's or page's once.
    pub fn take_messages(&mut self) -> Vec<String> {
        std::mem::take(&mut self.messages)
    }

    /// Whether the last view's choice is complete: every chosen node resident or failed,
    /// no page it reached still unread and no file it reached still unopened.
    pub fn stable(&self) -> bool {
        self.selection
            .nodes
            .iter()
            .all(|k| self.resident.contains_key(k) || self.failed.contains_key(k))
            && self
                .selection
                .pages
                .iter()
                .all(|k| self.failed_pages.contains_key(k))
            && self
                .selection
                .open
                .iter()
                .all(|t| self.failed_tiles.contains(t))
    }

    /// Whether what is left waits only for slots that frames still in flight may read (they
    /// are free a few frames on): a caller waiting within one frame should draw it instead.
    pub fn waits_for_slots(&self) -> bool {
        self.loader.pending() == 0 && !self.ready.is_empty() && !self.retiring.is_empty()
    }

    pub fn stats(&self) -> StreamStats {
        let drawn_points = self
            .selection
            .nodes
            .iter()
            .filter(|k| self.resident.contains_key(k))
            .map(|k| self.node_points(k))
            .sum();
        let slots = self.scene.streams.batch_count;
        StreamStats {
            selected_points: self.selection.points,
            drawn_points,
            selected_nodes: self.selection.nodes.len(),
            resident_nodes: self.resident.len(),
            loading: self.loader.pending(),
            bytes_read: self.loader.bytes_read(),
            slots,
            used_slots: self.resident.values().map(|r| r.slots.len() as u32).sum(),
            failed: self.failed.len() + self.failed_pages.len() + self.failed_tiles.len(),
            evicted: self.evicted,
            tiles_open: self.hierarchies.iter().filter(|h| h.is_some()).count(),
            tiles: self.hierarchies.len(),
            loader: self.loader.stats(),
        }
    }

    /// Waits up to `timeout` for a worker to finish something (a headless renderer with
    /// nothing to draw until then); returns whether one did.
    pub fn wait(&mut self, timeout: std::time::Duration) -> bool {
        let done = self.loader.wait(timeout);
        let any = !done.is_empty();
        self.absorb(done);
        any
    }

    /// One frame's streaming for `camera` on a `width` x `height` image (see the module
    /// documentation); then [`Self::batches`] is the frame's table.
    pub fn update(&mut self, camera: &Camera, width: u32, height: u32) -> Result<()> {
        self.frame += 1;
        while self
            .retiring
            .front()
            .is_some_and(|(at, _)| at + self.frames_in_flight <= self.frame)
        {
            let (_, slots) = self.retiring.pop_front().expect("checked");
            self.free.extend(slots.into_iter().map(Reverse));
        }
        self.refine(camera, width, height)
    }

    /// [`Self::update`] within the current frame (a frame may refine several times while it
    /// waits for nodes; slots freed now are still reused only frames later).
    pub fn refine(&mut self, camera: &Camera, width: u32, height: u32) -> Result<()> {
        let done = self.loader.poll();
        self.absorb(done);
        let aspect = width as f32 / height.max(1) as f32;
        let view = SelectView {
            view_proj: camera.projection(aspect) * camera.view(),
            eye: camera.eye,
            pixels_per_radian: height as f32 / (2.0 * (camera.fov_y * 0.5).tan()),
            error_px: self.options.error_px,
        };
        let budget = Budget {
            points: self.options.point_budget,
            slots: u64::from(self.scene.streams.batch_count),
        };
        let tiles = self.loader.tiles();
        // A file not opened has no octree cube yet: the selection reads its bounds instead.
        let unopened = crate::scene::copc::Info {
            center: glam::DVec3::ZERO,
            halfsize: 1.0,
            spacing: 1.0,
            root: (0, 0),
            gps_time: (0.0, 0.0),
        };
        let trees: Vec<Tree> = tiles
            .iter()
            .zip(&self.hierarchies)
            .enumerate()
            .map(|(i, (t, h))| Tree {
                hierarchy: if self.failed_tiles.contains(&i) {
                    Some(&EMPTY)
                } else {
                    h.as_ref()
                },
                info: t.file.as_ref().map_or(&unopened, |f| &f.info),
                bounds: t.bounds,
            })
            .collect();
        self.selection = select::select_forest(&trees, self.origin(), &view, budget);
        // Nodes decoded for an earlier view and no longer chosen are dropped.
        let chosen: HashSet<NodeId> = self.selection.nodes.iter().copied().collect();
        self.ready.retain(|k, _| chosen.contains(k));
        let mut bytes = UPLOAD_BYTES_PER_FRAME;
        let order = self.selection.nodes.clone();
        for key in &order {
            if self.ready.contains_key(key) && !self.place(*key, &mut bytes)? {
                break;
            }
        }
        self.uploader.finish()?;
        self.request();
        self.write_table();
        Ok(())
    }

    /// Takes in what the workers finished.
    fn absorb(&mut self, done: Vec<Done>) {
        for d in done {
            match d {
                Done::Opened { tile, result } => match result {
                    Ok(opened) => {
                        self.hierarchies[tile] = Some(opened.hierarchy);
                        self.ready.insert((tile, Key::ROOT), opened.root);
                    }
                    Err(e) => {
                        self.failed_tiles.insert(tile);
                        let t = &self.loader.tiles()[tile];
                        let message = t
                            .error
                            .clone()
                            .unwrap_or_else(|| format!("tile {}: {e}", t.href));
                        self.messages.push(message);
                    }
                },
                Done::Page {
                    tile,
                    key,
                    at,
                    entries,
                } => match entries {
                    Ok(entries) => {
                        let added = self.hierarchies[tile]
                            .as_mut()
                            .is_some_and(|h| h.add_page(at, entries));
                        if !added {
                            self.fail_page((tile, key), format!("the hierarchy page at byte {at} is referenced twice (a cycle); skipped"));
                        }
                    }
                    Err(e) => self.fail_page(
                        (tile, key),
                        format!("hierarchy page of node {key} skipped: {e}"),
                    ),
                },
                Done::Node { tile, key, result } => match result {
                    Ok(node) => {
                        self.ready.insert((tile, key), node);
                    }
                    Err(e) => {
                        let at = self.hierarchies[tile]
                            .as_ref()
                            .and_then(|h| h.nodes.get(&key))
                            .map_or(0, |n| n.offset);
                        let message = format!("node {key} (chunk at byte {at}) skipped: {e}");
                        self.messages.push(message.clone());
                        self.failed.insert((tile, key), message);
                    }
                },
            }
        }
    }

    fn fail_page(&mut self, key: NodeId, message: String) {
        if let Some(h) = self.hierarchies[key.0].as_mut() {
            h.pages.remove(&key.1);
        }
        self.messages.push(message.clone());
        self.failed_pages.insert(key, message);
    }

    /// Copies ready node `key` into free slots (evicting nodes the view does not draw when
    /// needed) within the frame's upload `budget`; false when it could not be placed now.
    fn place(&mut self, key: NodeId, budget: &mut u64) -> Result<bool> {
        let node = &self.ready[&key];
        let bytes = node.data.len() as u64;
        if bytes > STAGING_BYTES {
            let node = self.ready.remove(&key).expect("ready");
            let message = format!(
                "node {} skipped: {} points ({bytes} bytes) exceed the {STAGING_BYTES}-byte staging buffer",
                key.1,
                node.points
            );
            self.messages.push(message.clone());
            self.failed.insert(key, message);
            return Ok(true);
        }
        if bytes > *budget {
            return Ok(false);
        }
        let need = node.batches.len();
        if self.free.len() < need {
            self.evict(need - self.free.len());
        }
        if self.free.len() < need {
            return Ok(false);
        }
        let node = self.ready.remove(&key).expect("ready");
        *budget -= bytes;
        if self.counted.insert(key) {
            for &(class, count) in &node.classes {
                *self.classes.entry(class).or_default() += count;
            }
        }
        let slots: Vec<u32> = (0..need)
            .map(|_| self.free.pop().expect("counted").0)
            .collect();
        let n = u64::from(node.points);
        let mut copies = Vec::with_capacity(need * self.targets.len());
        let mut base = 0;
        for &(stream, buffer) in &self.targets {
            for (b, &slot) in slots.iter().enumerate() {
                let start = b as u64 * u64::from(BATCH_POINTS);
                let count = (n - start).min(u64::from(BATCH_POINTS));
                copies.push(CopyRegion {
                    dst: buffer,
                    dst_offset: StreamLayout::stream_bytes(
                        stream,
                        u64::from(slot) * u64::from(BATCH_POINTS),
                    ),
                    src_offset: base + StreamLayout::stream_bytes(stream, start),
                    size: StreamLayout::stream_bytes(stream, count),
                });
            }
            base += StreamLayout::stream_bytes(stream, n);
        }
        if n > 0 {
            self.uploader.upload(
                |staging| {
                    staging[..node.data.len()].copy_from_slice(&node.data);
                    Ok(())
                },
                &copies,
            )?;
        }
        let batches = node
            .batches
            .iter()
            .zip(&slots)
            .map(|(b, &slot)| GpuBatch {
                first: slot * BATCH_POINTS,
                ..*b
            })
            .collect();
        self.resident.insert(
            key,
            Resident {
                slots,
                batches,
                last_drawn: self.frame,
            },
        );
        Ok(true)
    }

    /// Evicts up to `slots` slots' worth of resident nodes the current view does not choose,
    /// least recently drawn first.
    fn evict(&mut self, slots: usize) {
        let chosen: HashSet<&NodeId> = self.selection.nodes.iter().collect();
        let mut idle: Vec<(u64, NodeId)> = self
            .resident
            .iter()
            .filter(|(k, _)| !chosen.contains(k))
            .map(|(k, r)| (r.last_drawn, *k))
            .collect();
        idle.sort();
        let mut freed = Vec::new();
        for (_, key) in idle {
            if freed.len() >= slots {
                break;
            }
            let r = self.resident.remove(&key).expect("resident");
            freed.extend(r.slots);
            self.evicted += 1;
        }
        if !freed.is_empty() {
            self.retiring.push_back((self.frame, freed));
        }
    }

    /// Hands the loader the files to open, the chosen nodes that are missing and the pages the
    /// view reached, most wanted first (at most a few per worker, so a changed view is served
    /// soon).
    fn request(&mut self) {
        let limit = 4 * self.options.loader.threads.max(1);
        let open = self
            .selection
            .open
            .iter()
            .filter(|t| !self.failed_tiles.contains(t))
            .map(|&t| Job::Open(t));
        let pages = self
            .selection
            .pages
            .iter()
            .filter(|k| !self.failed_pages.contains_key(k))
            .filter_map(|&(tile, key)| {
                let h = self.hierarchies[tile].as_ref()?;
                h.pages
                    .get(&key)
                    .map(|&(at, len)| Job::Page { tile, key, at, len })
            });
        let nodes = self
            .selection
            .nodes
            .iter()
            .filter(|k| {
                !self.resident.contains_key(k)
                    && !self.ready.contains_key(k)
                    && !self.failed.contains_key(k)
            })
            .filter_map(|&(tile, key)| {
                let node = self.hierarchies[tile].as_ref()?.nodes.get(&key)?;
                Some(Job::Node(tile, *node))
            });
        let jobs: Vec<Job> = open.chain(pages).chain(nodes).take(limit).collect();
        self.loader.request(&jobs);
    }

    /// The frame's batch table: the chosen resident nodes' batches, every other slot empty.
    fn write_table(&mut self) {
        for (slot, b) in self.table.iter_mut().enumerate() {
            *b = GpuBatch {
                first: slot as u32 * BATCH_POINTS,
                ..GpuBatch::default()
            };
        }
        let mut end = 0;
        for key in &self.selection.nodes {
            if let Some(r) = self.resident.get_mut(key) {
                r.last_drawn = self.frame;
                for (&slot, b) in r.slots.iter().zip(&r.batches) {
                    self.table[slot as usize] = *b;
                    end = end.max(slot + 1);
                }
            }
        }
        // Draws of every index stop after the last slot drawn (slots are taken lowest first).
        self.scene.draw_points.set(end * BATCH_POINTS);
    }

    /// The points of the nodes drawn this frame that `near` accepts (given one of a node's
    /// batch boxes, local frame), read again from their files: one cloud in the scene's local
    /// frame, and per node its first point in that cloud and its name ("HREF node KEY"). The
    /// GPU pool holds only encoded streams, so a tool that needs a drawn point's attributes
    /// (picking, measuring) reads the few nodes under the cursor; a node that cannot be read
    /// again is left out with a message.
    pub fn drawn_points(
        &mut self,
        near: impl Fn(&GpuBatch) -> bool,
    ) -> (Cloud, Vec<(usize, String)>) {
        let wanted: Vec<(TileId, crate::scene::copc::Node)> = self
            .selection
            .nodes
            .iter()
            .filter(|id| {
                self.resident
                    .get(id)
                    .is_some_and(|r| r.batches.iter().any(&near))
            })
            .filter_map(|id| {
                let node = self.hierarchies[id.0].as_ref()?.nodes.get(&id.1)?;
                Some((id.0, *node))
            })
            .collect();
        let mut parts = Vec::new();
        let mut names = Vec::new();
        let mut first = 0;
        for ((tile, node), read) in wanted.iter().zip(self.loader.read_points(&wanted)) {
            let href = &self.loader.tiles()[*tile].href;
            match read {
                Ok(cloud) => {
                    names.push((first, format!("{href} node {}", node.key)));
                    first += cloud.len();
                    parts.push(cloud);
                }
                Err(e) => self.messages.push(format!(
                    "{href} node {} not read for the tool: {e}",
                    node.key
                )),
            }
        }
        let mut cloud = Cloud::concat(parts);
        cloud.origin = self.info.origin;
        (cloud, names)
    }

    /// The centre and radius of the cloud's bounds (local frame), for framing a camera.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        (self.info.centre, self.info.radius)
    }
}

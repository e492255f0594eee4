//! The frame loop shared by the headless renderer, the benchmark and the viewer: on an
//! uploaded scene (`crate::gpu_scene`), builds one method's graph once, keeps frames in flight (`FrameRing`), updates each
//! slot's uniforms, submits, reads back.

pub mod settings;

use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use ash::vk;
use bytemuck::Zeroable;
use glam::Vec4;
use gpu_allocator::MemoryLocation;

use crate::frame::Frame;
use crate::gpu::{Buffer, Context, FrameRing, ImageDesc, SampleWindow, ScopeStats, Series};
use crate::gpu_scene::{GpuScene, SceneInfo};
use crate::graph::{Access, BufferId, CompiledGraph, GraphBuilder, ImageId};
use crate::layout::{
    FrameBlock, GpuBatch, COLOR_NONE, FLAG_CLIP, FLAG_CLIP_OUTSIDE, FLAG_FILTER, FLAG_HAS_NORMALS,
    FLAG_UNLIT,
};
use crate::methods::{
    BuildContext, MethodConfig, SampleCounters, Targets, COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT,
};
use crate::overlay::{pass::OverlayPass, Mark, Panel};
use crate::post::{self, PostOptions};
use crate::scene::clip::{Keep, Resolved};
use crate::scene::{lights, Camera, Light};

use crate::frame::MAX_EDGE;

/// Bytes of one `GpuBatch`.
const BATCH_BYTES: u64 = std::mem::size_of::<GpuBatch>() as u64;

/// Per-frame settings.
#[derive(Clone, Debug)]
pub struct View {
    pub camera: Camera,
    pub lights: Vec<Light>,
    /// Color by the scene's `Coloring` (`SceneInfo::coloring`); `false` shows the lit base
    /// color.
    pub use_color: bool,
    /// Seconds, for orbiting lights.
    pub time: f32,
}

/// Ambient weight of the default shading (`shade` in `glsl/common/common.glsl`).
pub const AMBIENT: f32 = 0.25;
/// Specular weight (tinted by the albedo); the diffuse weight is `1 - AMBIENT - SPECULAR`.
pub const SPECULAR: f32 = 0.15;
/// Blinn-Phong exponent.
pub const SPECULAR_EXPONENT: f32 = 32.0;

/// Frames in flight unless `RendererOptions::frames_in_flight` says otherwise.
pub const DEFAULT_FRAMES_IN_FLIGHT: usize = 2;

/// What a renderer adds around the method (readback, present, overlay, post) and how many
/// frames it keeps in flight.
#[derive(Clone, Copy, Debug)]
pub struct RendererOptions {
    /// Add on-demand readback passes (color, depth, normal to host buffers).
    pub readback: bool,
    /// Add a blit to an external (swapchain) image of this format and size, and a present pass.
    pub present: Option<ImageDesc>,
    /// Frame slots (command buffer, fence, timestamp pool, frame uniforms), at least 1.
    pub frames_in_flight: usize,
    /// Draw the viewer's text overlay over the color target (before present and readback);
    /// its text is set per frame with `Renderer::set_overlay`.
    pub overlay: bool,
    /// Post-processing after the method (eye-dome lighting, background); none by default, so
    /// the evaluation scores the method's own targets.
    pub post: PostOptions,
    /// Count each pass's shader invocations beside its time (pipeline statistics queries,
    /// which may perturb the timings).
    pub pipeline_statistics: bool,
}

impl Default for RendererOptions {
    fn default() -> Self {
        Self {
            readback: false,
            present: None,
            frames_in_flight: DEFAULT_FRAMES_IN_FLIGHT,
            overlay: false,
            post: PostOptions::NONE,
            pipeline_statistics: false,
        }
    }
}

struct Readback {
    color: Arc<Buffer>,
    depth: Arc<Buffer>,
    normal: Arc<Buffer>,
}

/// The per-level sample counts of a method that publishes them (`SampleCounters`), copied
/// every frame into the frame slot's host-visible buffer and read after the slot's fence.
struct Samples {
    /// Per frame slot: the counts of the slot's last frame, bound to the graph's external
    /// buffer `id` before the slot is recorded.
    host: Vec<Buffer>,
    id: BufferId,
    levels: usize,
    /// Per frame slot: a frame was submitted whose counts were not read yet.
    pending: Vec<bool>,
    /// The newest finished frame's counts (`levels` long; empty before a frame was read).
    counts: Vec<u64>,
}

impl Samples {
    /// Reads `slot`'s counts if its frame (finished: its fence was waited on) was not read.
    fn collect(&mut self, slot: usize) -> Result<()> {
        if !std::mem::take(&mut self.pending[slot]) {
            return Ok(());
        }
        let bytes = &self.host[slot].mapped()?[..4 * self.levels];
        self.counts.clear();
        self.counts.extend(
            bytemuck::cast_slice::<u8, u32>(bytes)
                .iter()
                .map(|&n| u64::from(n)),
        );
        Ok(())
    }
}

/// One method's compiled graph and what it needs every frame.
///
/// Frames in flight: each slot of `frames` has its own command buffer, fence, timestamp query
/// pool (in the graph's profiler) and frame-uniform buffer, bound to the graph's external
/// `frame` buffer before the slot is recorded. The host writes slot `k`'s uniforms and
/// re-records its command buffer only after slot `k`'s fence. All slots share the graph's
/// transient and history resources: that is legal because every frame is submitted to the
/// one queue, and the steady-state barriers (derived from the previous frame's accesses) make
/// each frame's first use of a resource wait for the previous frame's last use of it, so
/// frame N+1 is ordered after frame N on the GPU where they touch the same memory.
pub struct Renderer {
    ctx: Arc<Context>,
    graph: CompiledGraph,
    frames: FrameRing,
    /// Per frame slot: the frame uniforms.
    uniforms: Vec<Buffer>,
    frame_id: BufferId,
    readback: Option<Readback>,
    samples: Option<Samples>,
    overlay: Option<OverlayPass>,
    /// The swapchain image slot when presenting.
    pub present_target: Option<ImageId>,
    pub width: u32,
    pub height: u32,
    pub info: SceneInfo,
    pub config: MethodConfig,
    schedule: String,
    segment_points: u32,
    batch_count: u32,
    /// Per frame slot, a streamed scene's batch table (empty for a loaded scene).
    batch_tables: Vec<Buffer>,
    batches_id: BufferId,
    /// The viewer's clipping box and hidden classes (`set_filter`), applied by the
    /// projection passes.
    filter: Option<Resolved>,
    /// The host's side of each timed frame: recording and submission.
    cpu: CpuTimes,
}

/// Per frame (the last `profiler::WINDOW`), when the host began recording it (milliseconds
/// since the renderer was built) and how long recording and submission took.
struct CpuTimes {
    epoch: Instant,
    /// `epoch` on the host's monotonic clock (`gpu::context::monotonic_ms`), for calibration.
    epoch_monotonic_ms: f64,
    starts: SampleWindow,
    record: SampleWindow,
    submit: SampleWindow,
}

/// The raw timings of the frames recorded since the last `clear_timings`, oldest first: the
/// GPU's per pass (`Series`) and the host's per frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimingSeries {
    pub gpu: Series,
    /// When the host began recording each frame, milliseconds since the renderer was built.
    pub cpu_starts: Vec<f64>,
    /// Milliseconds the host spent recording each frame's commands.
    pub cpu_record: Vec<f64>,
    /// Milliseconds the host spent submitting each frame.
    pub cpu_submit: Vec<f64>,
    /// Milliseconds to add to a GPU time (`gpu.starts`) to place it on the host's clock of
    /// `cpu_starts`, where the device calibrates its timestamps against the host's
    /// (`Context::calibrate`); `None` elsewhere.
    pub gpu_to_host_ms: Option<f64>,
}

impl Renderer {
    /// Builds and compiles the graph of `config` for a `width` x `height` frame.
    pub fn new(
        ctx: &Arc<Context>,
        scene: &GpuScene,
        info: SceneInfo,
        config: &MethodConfig,
        width: u32,
        height: u32,
        options: RendererOptions,
    ) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_EDGE || height > MAX_EDGE {
            bail!("image size {width}x{height} must be within 1..={MAX_EDGE} per edge");
        }
        if let Some(why) = config.method.unsupported(&ctx.caps) {
            bail!(why);
        }
        let m = &config.method;
        if scene.streamed && (m.needs_lod || m.needs_hpr || m.needs_faces) {
            bail!(
                "method '{}' reads the whole cloud (its object texture, visibility or faces); a streamed file holds only the nodes a view needs: load it whole (without --stream) for this method",
                m.name
            );
        }
        if config.method.needs_lod && scene.lod.is_none() {
            bail!(
                "method '{}' needs the object texture of level of detail (upload with lod)",
                config.method.name
            );
        }
        if config.method.needs_normal_field && !scene.streams.normal_field {
            bail!(
                "method '{}' needs the splats' linear normal fields (upload with normal_field)",
                config.method.name
            );
        }
        if config.method.needs_faces && scene.indices.is_none() {
            bail!(
                "method '{}' needs an input with triangle faces",
                config.method.name
            );
        }
        let frame_bytes = std::mem::size_of::<FrameBlock>() as u64;
        let frame_usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let slots = options.frames_in_flight.max(1);
        let uniforms = (0..slots)
            .map(|_| {
                Buffer::new(
                    ctx,
                    "frame",
                    frame_bytes,
                    frame_usage,
                    MemoryLocation::CpuToGpu,
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let mut g = GraphBuilder::new();
        let output = |format| ImageDesc {
            format,
            width,
            height,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC,
        };
        let targets = Targets {
            color: g.image("color", output(COLOR_FORMAT)),
            depth: g.image("depth", output(DEPTH_FORMAT)),
            normal: g.image("normal", output(NORMAL_FORMAT)),
        };
        let frame_id = g.external_buffer("frame", frame_bytes, frame_usage);
        let segments_id = g.import_buffer("stream.segments", scene.streams.table.clone());
        let table_bytes = u64::from(scene.streams.batch_count.max(1)) * BATCH_BYTES;
        let batch_tables = if scene.streamed {
            (0..slots)
                .map(|_| {
                    Buffer::new(
                        ctx,
                        "stream.batches",
                        table_bytes,
                        vk::BufferUsageFlags::STORAGE_BUFFER,
                        MemoryLocation::CpuToGpu,
                    )
                })
                .collect::<Result<Vec<_>>>()?
        } else {
            Vec::new()
        };
        let batches_id = if scene.streamed {
            g.external_buffer(
                "stream.batches",
                table_bytes,
                vk::BufferUsageFlags::STORAGE_BUFFER,
            )
        } else {
            g.import_buffer("stream.batches", scene.streams.batches.clone())
        };
        let indices_id = scene
            .indices
            .as_ref()
            .map(|b| g.import_buffer("indices", b.clone()));
        let mut build = BuildContext {
            ctx,
            graph: &mut g,
            config,
            scene,
            frame: frame_id,
            segments: segments_id,
            batches: batches_id,
            indices: indices_id,
            targets,
            width,
            height,
            samples: None,
        };
        (config.method.build)(&mut build)?;
        let samples = build
            .samples
            .map(|counters| add_samples(ctx, &mut g, counters, slots))
            .transpose()?;
        // The post stage's color (or the method's, without post-processing) is what is shown.
        let shown = Targets {
            color: post::build(&mut g, targets, width, height, &options.post),
            ..targets
        };
        let overlay = if options.overlay {
            Some(OverlayPass::add(
                ctx,
                &mut g,
                shown.color,
                frame_id,
                slots,
                (width, height),
            )?)
        } else {
            None
        };
        let present_target = options
            .present
            .map(|desc| add_present(&mut g, shown.color, desc));
        let readback = if options.readback {
            Some(add_readback(ctx, &mut g, shown, width, height)?)
        } else {
            None
        };
        let culled = g.cull();
        let mut schedule = g.schedule()?;
        if !culled.is_empty() {
            schedule.push_str(&format!("culled (results unused): {}\n", culled.join(", ")));
        }
        let mut graph = g.compile_frames(ctx, slots)?;
        if options.pipeline_statistics {
            graph.profiler().enable_statistics()?;
        }
        Ok(Self {
            ctx: ctx.clone(),
            graph,
            frames: FrameRing::new(ctx, slots, present_target.is_some())?,
            uniforms,
            frame_id,
            readback,
            samples,
            overlay,
            present_target,
            width,
            height,
            info,
            config: config.clone(),
            schedule,
            segment_points: scene.streams.segment_points,
            batch_count: scene.streams.batch_count,
            batch_tables,
            batches_id,
            filter: None,
            cpu: CpuTimes {
                epoch: Instant::now(),
                epoch_monotonic_ms: crate::gpu::context::monotonic_ms(),
                starts: SampleWindow::default(),
                record: SampleWindow::default(),
                submit: SampleWindow::default(),
            },
        })
    }

    /// The graph's schedule (passes, accesses, derived barriers).
    pub fn schedule(&self) -> &str {
        &self.schedule
    }

    /// Number of frame slots.
    pub fn frames_in_flight(&self) -> usize {
        self.frames.len()
    }

    /// Starts the next frame: moves to the next slot, waits for the frame that last used it
    /// (not for the frames submitted since), collects that frame's timestamps and sample
    /// counts and binds the slot's uniforms and sample readback buffer. Returns the slot's
    /// swapchain image-available semaphore (null unless the renderer presents). Call before
    /// `update`, `record` and `submit`.
    pub fn begin_frame(&mut self) -> Result<vk::Semaphore> {
        let slot = self.frames.advance()?;
        self.graph.profiler().collect(slot)?;
        self.graph
            .bind_external_buffer(self.frame_id, &self.uniforms[slot]);
        if let Some(table) = self.batch_tables.get(slot) {
            self.graph.bind_external_buffer(self.batches_id, table);
        }
        if let Some(samples) = &mut self.samples {
            samples.collect(slot)?;
            self.graph
                .bind_external_buffer(samples.id, &samples.host[slot]);
        }
        if let Some(overlay) = &self.overlay {
            overlay.bind(&mut self.graph, slot);
        }
        Ok(self.frames.acquire_semaphore())
    }

    /// Writes the current slot's frame uniforms for `view` (the GPU is done with them:
    /// `begin_frame` waited for the slot's previous frame).
    pub fn update(&mut self, view: &View) -> Result<()> {
        let mut block = FrameBlock::zeroed();
        let v = view.camera.view();
        let p = view
            .camera
            .projection(self.width as f32 / self.height as f32);
        block.u.view = v;
        block.u.proj = p;
        block.u.view_proj = p * v;
        block.u.viewport = Vec4::new(
            self.width as f32,
            self.height as f32,
            1.0 / self.width as f32,
            1.0 / self.height as f32,
        );
        block.u.point_size = self.config.get("size").max(1.0);
        block.u.near = view.camera.near;
        block.u.ambient = AMBIENT;
        block.u.specular_exponent = SPECULAR_EXPONENT;
        block.u.specular = SPECULAR;
        block.u.base_color = Vec4::new(0.7, 0.7, 0.7, 1.0);
        // Without colors (`C` in the viewer, `--no-color`) every mode shows the lit base color.
        let coloring = self.info.coloring;
        let colored = view.use_color && coloring.mode != COLOR_NONE;
        block.u.color_mode = if colored { coloring.mode } else { COLOR_NONE };
        let [start, scale] = coloring.range_uniform();
        block.u.color_range = Vec4::new(start, scale, 0.0, 0.0);
        block.u.color_axis = coloring.axis.extend(0.0);
        block.u.flags = if self.info.has_normals {
            FLAG_HAS_NORMALS
        } else {
            0
        } | if (colored && coloring.unlit) || !self.info.has_normals {
            // Without normals there is nothing to light: the albedo as it is.
            FLAG_UNLIT
        } else {
            0
        };
        if let Some(filter) = &self.filter {
            if let Some((clip, keep)) = filter.clip {
                block.u.clip = clip;
                block.u.flags |= FLAG_CLIP
                    | if keep == Keep::Outside {
                        FLAG_CLIP_OUTSIDE
                    } else {
                        0
                    };
            }
            if !filter.hidden.is_empty() {
                let [a, b, c, d, e, f, g, h] = filter.hidden.0;
                block.u.class_hidden_lo = [a, b, c, d];
                block.u.class_hidden_hi = [e, f, g, h];
                block.u.flags |= FLAG_FILTER;
            }
        }
        block.u.point_count = self.info.points;
        block.u.segment_points = self.segment_points;
        block.u.batch_count = self.batch_count;
        let resolved = lights::resolve(
            &view.lights,
            v,
            (self.info.centre, self.info.radius),
            self.info.up,
            view.time,
        );
        for (slot, light) in block.lights.iter_mut().zip(resolved) {
            *slot = light;
            block.u.light_count += 1;
        }
        self.uniforms[self.frames.current()].write(bytemuck::bytes_of(&block))
    }

    /// Sets the clipping box and hidden classes the projection passes apply from the next
    /// `update` on (`None`: every point). Hidden classes need the scene's `Classes` stream
    /// (`GpuStreams::add_classes`); without it they hide nothing.
    pub fn set_filter(&mut self, filter: Option<Resolved>) {
        self.filter = filter;
    }

    /// Writes the current slot's batch table (after `begin_frame`, before `record`): for a
    /// streamed scene, which batch slots hold which points this frame.
    pub fn set_batches(&mut self, batches: &[GpuBatch]) -> Result<()> {
        let Some(table) = self.batch_tables.get(self.frames.current()) else {
            bail!("set_batches: the scene is not streamed (its batch table is fixed)");
        };
        if batches.len() != self.batch_count as usize {
            bail!(
                "set_batches: {} batches for a pool of {}",
                batches.len(),
                self.batch_count
            );
        }
        table.write(bytemuck::cast_slice(batches))
    }

    /// Sets the current slot's overlay text (after `begin_frame`, before `record`); returns the
    /// quads drawn. A renderer built without `RendererOptions::overlay` draws nothing and returns 0.
    pub fn set_overlay(&mut self, panels: &[Panel], marks: &[Mark]) -> Result<usize> {
        let slot = self.frames.current();
        match &mut self.overlay {
            Some(overlay) => overlay.write(slot, panels, marks),
            None => Ok(0),
        }
    }

    /// Records the frame into the current slot's command buffer.
    pub fn record(&mut self, readback: bool) -> Result<()> {
        let start = Instant::now();
        let cmd = self.frames.begin()?;
        let slot = self.frames.current();
        self.graph
            .record(cmd, slot, readback && self.readback.is_some());
        self.frames.end()?;
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        self.cpu.starts.push(ms(start - self.cpu.epoch));
        self.cpu.record.push(ms(start.elapsed()));
        Ok(())
    }

    /// Submits the current slot and returns without waiting for it. `wait` (the swapchain
    /// acquire semaphore) is waited on before the frame writes the swapchain image; `signal`
    /// is signalled when the frame is done (for present).
    pub fn submit(
        &mut self,
        wait: Option<vk::Semaphore>,
        signal: Option<vk::Semaphore>,
    ) -> Result<()> {
        let start = Instant::now();
        self.frames.submit(wait, signal)?;
        self.cpu.submit.push(start.elapsed().as_secs_f64() * 1e3);
        if let Some(samples) = &mut self.samples {
            samples.pending[self.frames.current()] = true;
        }
        Ok(())
    }

    /// Blocks until every submitted frame has finished and collects their timestamps and
    /// sample counts, oldest first (so `last_timings` and `samples_per_level` report the
    /// newest frame).
    pub fn finish(&mut self) -> Result<()> {
        let (len, current) = (self.frames.len(), self.frames.current());
        for i in 1..=len {
            let slot = (current + i) % len;
            self.frames.wait(slot)?;
            self.graph.profiler().collect(slot)?;
            if let Some(samples) = &mut self.samples {
                samples.collect(slot)?;
            }
        }
        Ok(())
    }

    /// The samples the method drew per level in the newest finished frame (the level-of-detail
    /// methods' vertices emitted per level of the object texture); `None` for methods that do
    /// not count them and before a frame finished.
    pub fn samples_per_level(&self) -> Option<&[u64]> {
        self.samples
            .as_ref()
            .filter(|s| !s.counts.is_empty())
            .map(|s| s.counts.as_slice())
    }

    /// Renders one frame and waits for it (and for any frame still in flight); returns the
    /// read-back frame when asked (and built with `RendererOptions::readback`).
    pub fn render(&mut self, view: &View, readback: bool) -> Result<Option<Frame>> {
        self.render_batches(view, None, readback)
    }

    /// [`Self::render`] of a streamed scene with this frame's batch table.
    pub fn render_batches(
        &mut self,
        view: &View,
        batches: Option<&[GpuBatch]>,
        readback: bool,
    ) -> Result<Option<Frame>> {
        self.begin_frame()?;
        if let Some(batches) = batches {
            self.set_batches(batches)?;
        }
        self.update(view)?;
        self.record(readback)?;
        self.submit(None, None)?;
        self.finish()?;
        if readback {
            self.read_frame().map(Some)
        } else {
            Ok(None)
        }
    }

    /// Binds this frame's swapchain image.
    pub fn bind_present_image(&mut self, image: vk::Image, view: vk::ImageView) {
        if let Some(id) = self.present_target {
            self.graph.bind_external(id, image, view);
        }
    }

    /// Forgets timing samples (after warm-up).
    pub fn clear_timings(&mut self) {
        self.graph.profiler().clear();
        self.cpu.starts.clear();
        self.cpu.record.clear();
        self.cpu.submit.clear();
    }

    /// The raw timings of every frame since `clear_timings` (at most `profiler::WINDOW`).
    pub fn timing_series(&mut self) -> TimingSeries {
        TimingSeries {
            gpu: self.graph.profiler().series(),
            cpu_starts: self.cpu.starts.ordered(),
            cpu_record: self.cpu.record.ordered(),
            cpu_submit: self.cpu.submit.ordered(),
            gpu_to_host_ms: self
                .ctx
                .calibrate()
                .map(|(device, host)| host - self.cpu.epoch_monotonic_ms - device),
        }
    }

    /// Per-pass GPU time statistics and the whole frame's.
    pub fn timings(&mut self) -> (Vec<ScopeStats>, ScopeStats) {
        let p = self.graph.profiler();
        (p.scopes(), p.frame())
    }

    /// The last frame's per-pass milliseconds (for the viewer's title).
    pub fn last_timings(&mut self) -> Vec<(String, f64)> {
        self.graph.profiler().last()
    }

    /// The frame read back by the last finished frame recorded with readback (built with
    /// `RendererOptions::readback`; call after `finish`).
    pub fn read_frame(&self) -> Result<Frame> {
        let rb = self
            .readback
            .as_ref()
            .context("renderer was built without readback")?;
        let n = self.width as usize * self.height as usize;
        let color: Vec<[u8; 4]> = bytemuck::cast_slice(&rb.color.mapped()?[..n * 4]).to_vec();
        let depth: Vec<f32> = bytemuck::cast_slice::<u8, f32>(&rb.depth.mapped()?[..n * 4])
            .iter()
            .map(|&d| {
                if d > 0.0 && d.is_finite() {
                    d
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        let normal: Vec<[f32; 3]> =
            bytemuck::cast_slice::<u8, [u16; 4]>(&rb.normal.mapped()?[..n * 8])
                .iter()
                .map(|h| [0, 1, 2].map(|i| half::f16::from_bits(h[i]).to_f32()))
                .collect();
        Ok(Frame {
            width: self.width,
            height: self.height,
            color,
            depth,
            normal: Some(normal),
        })
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        // SAFETY: wait for every in-flight use of the graph's resources before they drop.
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
        }
    }
}

fn add_readback(
    ctx: &Arc<Context>,
    g: &mut GraphBuilder,
    t: Targets,
    width: u32,
    height: u32,
) -> Result<Readback> {
    let n = width as u64 * height as u64;
    let host = |name: &str, bytes: u64| Buffer::readback(ctx, name, bytes).map(Arc::new);
    let rb = Readback {
        color: host("readback.color", n * 4)?,
        depth: host("readback.depth", n * 4)?,
        normal: host("readback.normal", n * 8)?,
    };
    let ids = [
        (t.color, g.import_buffer("readback.color", rb.color.clone())),
        (t.depth, g.import_buffer("readback.depth", rb.depth.clone())),
        (
            t.normal,
            g.import_buffer("readback.normal", rb.normal.clone()),
        ),
    ];
    let mut copy = g.pass("readback").on_demand();
    for (image, buffer) in ids {
        copy = copy
            .image(image, Access::TransferSrc)
            .buffer(buffer, Access::TransferDst);
    }
    copy.record(move |ctx| {
        for (image, buffer) in ids {
            ctx.copy_image_to_buffer(image, 0, buffer);
        }
    });
    // Makes the copies visible to the host after the frame's fence; records no commands.
    let mut host_pass = g.pass("readback.host").on_demand();
    for (_, buffer) in ids {
        host_pass = host_pass.buffer(buffer, Access::HostRead);
    }
    host_pass.record(|_| {});
    Ok(rb)
}

/// Declares the copy of `counters` into an external buffer bound per frame slot to one of
/// `slots` host-visible buffers (`samples.copy`, every frame) and its hand-over to the host
/// (`samples.host`, which keeps the copy from being culled).
fn add_samples(
    ctx: &Arc<Context>,
    g: &mut GraphBuilder,
    counters: SampleCounters,
    slots: usize,
) -> Result<Samples> {
    let levels = counters.levels as usize;
    let bytes = 4 * u64::from(counters.levels);
    let host = (0..slots)
        .map(|_| Buffer::readback(ctx, "samples", bytes))
        .collect::<Result<Vec<_>>>()?;
    let id = g.external_buffer("samples", bytes, vk::BufferUsageFlags::TRANSFER_DST);
    let region = vk::BufferCopy {
        src_offset: counters.offset,
        dst_offset: 0,
        size: bytes,
    };
    g.copy_buffer("samples.copy", counters.buffer, id, &[region]);
    g.pass("samples.host")
        .buffer(id, Access::HostRead)
        .record(|_| {});
    Ok(Samples {
        host,
        id,
        levels,
        pending: vec![false; slots],
        counts: Vec::with_capacity(levels),
    })
}

fn add_present(g: &mut GraphBuilder, color: ImageId, desc: ImageDesc) -> ImageId {
    let swapchain = g.external_image("swapchain", desc);
    g.pass("present.blit")
        .image(color, Access::TransferSrc)
        .image(swapchain, Access::TransferDst)
        .record(move |ctx| ctx.blit(color, 0, swapchain, 0));
    g.pass("present.transition")
        .image(swapchain, Access::Present)
        .record(|_| {});
    swapchain
}

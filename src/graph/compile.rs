//! Compiling a `GraphBuilder`: culling, barrier derivation for the device's stages, usage
//! flags of graph-owned resources derived from their accesses, allocation, mip-range views,
//! samplers and timestamp scopes.

use std::collections::HashMap;
use std::ffi::CString;
use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use super::derive::{derive, Barrier, BarrierTarget};
use super::sync::StageSupport;
use super::{
    Access, BufferId, BufferSource, GraphBuilder, ImageId, ImageSource, PassDecl, Subresource,
};
use crate::gpu::memory::create_view;
use crate::gpu::{Buffer, Context, Image, ImageDesc, Pipeline, Profiler};

pub(super) enum ImageSlot {
    Owned(Image),
    /// A graph-allocated image no kept pass uses (e.g. the second image of a pyramid whose
    /// upper levels a configuration skips): not allocated.
    Unused(ImageDesc),
    Imported(Arc<Image>),
    External {
        desc: ImageDesc,
        raw: vk::Image,
        view: vk::ImageView,
    },
}

pub(super) enum BufferSlot {
    Owned(Buffer),
    /// A transient buffer no pass left after culling reads or writes: not allocated.
    Unused(u64),
    Imported(Arc<Buffer>),
    External {
        size: u64,
        usage: vk::BufferUsageFlags,
        raw: vk::Buffer,
    },
}

/// One pass's barriers as Vulkan structures, resolved to handles at compile time so that
/// recording allocates nothing. External resources are patched in place when bound.
#[derive(Default)]
pub(super) struct BarrierBatch {
    pub images: Vec<vk::ImageMemoryBarrier2<'static>>,
    /// The graph image of each entry of `images`.
    image_ids: Vec<ImageId>,
    pub buffers: Vec<vk::BufferMemoryBarrier2<'static>>,
    /// The graph buffer of each entry of `buffers`.
    buffer_ids: Vec<BufferId>,
}

impl BarrierBatch {
    fn new(graph: &CompiledGraph, barriers: &[Barrier]) -> Self {
        let mut batch = Self::default();
        for b in barriers {
            let t = b.transition;
            match b.target {
                BarrierTarget::Image { id, mip } => {
                    let desc = graph.image_desc(id);
                    let range = vk::ImageSubresourceRange {
                        aspect_mask: desc.aspect(),
                        base_mip_level: mip,
                        level_count: 1,
                        base_array_layer: 0,
                        layer_count: 1,
                    };
                    batch.images.push(
                        vk::ImageMemoryBarrier2::default()
                            .src_stage_mask(t.src_stages)
                            .src_access_mask(t.src_access)
                            .dst_stage_mask(t.dst_stages)
                            .dst_access_mask(t.dst_access)
                            .old_layout(t.old_layout)
                            .new_layout(t.new_layout)
                            .image(graph.image_raw(id))
                            .subresource_range(range),
                    );
                    batch.image_ids.push(id);
                }
                BarrierTarget::Buffer { id, range } => {
                    let (raw, size) = graph.buffer_raw(id);
                    let end = range.end().min(size);
                    batch.buffers.push(
                        vk::BufferMemoryBarrier2::default()
                            .src_stage_mask(t.src_stages)
                            .src_access_mask(t.src_access)
                            .dst_stage_mask(t.dst_stages)
                            .dst_access_mask(t.dst_access)
                            .buffer(raw)
                            .offset(range.offset)
                            .size(end - range.offset),
                    );
                    batch.buffer_ids.push(id);
                }
            }
        }
        batch
    }

    pub fn is_empty(&self) -> bool {
        self.images.is_empty() && self.buffers.is_empty()
    }

    fn patch_image(&mut self, id: ImageId, raw: vk::Image) {
        entries_of(&mut self.images, &self.image_ids, id).for_each(|b| b.image = raw);
    }

    fn patch_buffer(&mut self, id: BufferId, raw: vk::Buffer) {
        entries_of(&mut self.buffers, &self.buffer_ids, id).for_each(|b| b.buffer = raw);
    }
}

/// The barriers among `barriers` whose graph resource (the same entry of `ids`) is `id`.
fn entries_of<'a, B, I: PartialEq>(
    barriers: &'a mut [B],
    ids: &'a [I],
    id: I,
) -> impl Iterator<Item = &'a mut B> {
    barriers
        .iter_mut()
        .zip(ids)
        .filter(move |(_, i)| **i == id)
        .map(|(b, _)| b)
}

pub(super) struct CompiledPass {
    pub decl: PassDecl,
    pub label: CString,
    /// Barriers before the pass in the first frame.
    pub first: BarrierBatch,
    /// Barriers before the pass in every later frame.
    pub steady: BarrierBatch,
    /// Index of the pass's timestamp scope (regular passes only).
    pub scope: Option<usize>,
    /// The pipeline of a `compute` or `draw` pass.
    pub pipeline: Option<Arc<Pipeline>>,
}

/// An executable graph: resources allocated, barriers derived, scopes assigned.
pub struct CompiledGraph {
    pub(super) ctx: Arc<Context>,
    pub(super) images: Vec<(String, ImageSlot)>,
    pub(super) buffers: Vec<(String, BufferSlot)>,
    pub(super) passes: Vec<CompiledPass>,
    pub(super) profiler: Profiler,
    /// Samplers by `Sampler as usize`.
    pub(super) samplers: [vk::Sampler; 2],
    /// Views of declared multi-level mip ranges `(image, base, count)` that are not the whole
    /// chain (single levels and the whole chain have views on the image itself).
    pub(super) range_views: HashMap<(ImageId, u32, u32), vk::ImageView>,
    pub(super) first_frame: bool,
}

/// The optional stages `ctx`'s device has enabled.
fn stage_support(ctx: &Context) -> StageSupport {
    StageSupport {
        geometry: ctx.caps.geometry_shader,
        task: ctx.caps.task_shader,
        mesh: ctx.caps.mesh_shader,
    }
}

impl GraphBuilder {
    /// The usage flags of every image and buffer: the declared ones plus those their accesses
    /// need.
    fn derived_usage(&self) -> (Vec<vk::ImageUsageFlags>, Vec<vk::BufferUsageFlags>) {
        let mut images: Vec<_> = self.images.iter().map(|r| r.desc().usage).collect();
        let mut buffers: Vec<_> =
            self.buffers
                .iter()
                .map(|r| match &r.source {
                    BufferSource::Transient { usage, .. }
                    | BufferSource::External { usage, .. } => *usage,
                    BufferSource::Imported(b) => b.usage,
                })
                .collect();
        for pass in &self.passes {
            for (sub, access) in &pass.uses {
                match *sub {
                    Subresource::Image { id, .. } => {
                        images[id.0 as usize] |= access.image_usage();
                    }
                    Subresource::Buffer(id, _) => {
                        buffers[id.0 as usize] |= access.buffer_usage();
                    }
                }
            }
        }
        (images, buffers)
    }

    /// `compile_frames` for one frame in flight.
    pub fn compile(self, ctx: &Arc<Context>) -> Result<CompiledGraph> {
        self.compile_frames(ctx, 1)
    }

    /// Validates, culls unused passes, derives barriers for `ctx`'s device, allocates graph-owned
    /// resources (their usage derived from their accesses), views and timestamp scopes (one
    /// query pool per frame slot: `record` takes the slot, `0..frames_in_flight`).
    pub fn compile_frames(
        mut self,
        ctx: &Arc<Context>,
        frames_in_flight: usize,
    ) -> Result<CompiledGraph> {
        self.cull();
        let barriers = derive(&self, stage_support(ctx))?;
        let (image_usage, buffer_usage) = self.derived_usage();
        let mut ranges: Vec<(ImageId, u32, u32)> = Vec::new();
        for pass in &self.passes {
            for (sub, access) in &pass.uses {
                if let (Subresource::Image { id, base, count }, Access::Sampled(_)) = (*sub, access)
                {
                    let levels = self.desc(id).mip_levels;
                    if count > 1 && count < levels && !ranges.contains(&(id, base, count)) {
                        ranges.push((id, base, count));
                    }
                }
            }
        }
        let mut used = vec![false; self.images.len()];
        let mut buffer_used = vec![false; self.buffers.len()];
        for pass in &self.passes {
            for (sub, _) in &pass.uses {
                match sub {
                    Subresource::Image { id, .. } => used[id.0 as usize] = true,
                    Subresource::Buffer(id, _) => buffer_used[id.0 as usize] = true,
                }
            }
        }
        let images = self
            .images
            .into_iter()
            .zip(image_usage)
            .zip(used)
            .map(|((r, usage), used)| {
                let slot = match r.source {
                    ImageSource::Transient(d) | ImageSource::History(d) if !used => {
                        ImageSlot::Unused(d)
                    }
                    ImageSource::Transient(d) | ImageSource::History(d) => {
                        ImageSlot::Owned(Image::new(ctx, &r.name, ImageDesc { usage, ..d })?)
                    }
                    ImageSource::Imported(i) => ImageSlot::Imported(i),
                    ImageSource::External(desc) => ImageSlot::External {
                        desc,
                        raw: vk::Image::null(),
                        view: vk::ImageView::null(),
                    },
                };
                Ok((r.name, slot))
            })
            .collect::<Result<Vec<_>>>()?;
        let buffers = self
            .buffers
            .into_iter()
            .zip(buffer_usage)
            .zip(buffer_used)
            .map(|((r, usage), used)| {
                let slot = match r.source {
                    BufferSource::Transient { size, .. } if !used => BufferSlot::Unused(size),
                    BufferSource::Transient { size, .. } => BufferSlot::Owned(Buffer::new(
                        ctx,
                        &r.name,
                        size,
                        usage,
                        gpu_allocator::MemoryLocation::GpuOnly,
                    )?),
                    BufferSource::Imported(b) => BufferSlot::Imported(b),
                    BufferSource::External { size, usage } => BufferSlot::External {
                        size,
                        usage,
                        raw: vk::Buffer::null(),
                    },
                };
                Ok((r.name, slot))
            })
            .collect::<Result<Vec<_>>>()?;
        let scope_names: Vec<String> = self
            .passes
            .iter()
            .filter(|p| !p.on_demand)
            .map(|p| p.name.clone())
            .collect();
        let mut graph = CompiledGraph {
            ctx: ctx.clone(),
            profiler: Profiler::new(ctx, scope_names, frames_in_flight)?,
            images,
            buffers,
            passes: Vec::with_capacity(self.passes.len()),
            samplers: [vk::Sampler::null(); 2],
            range_views: HashMap::new(),
            first_frame: true,
        };
        // Objects created below are destroyed by `graph`'s Drop, also on an early return.
        for (i, (filter, mipmap)) in [
            (vk::Filter::NEAREST, vk::SamplerMipmapMode::NEAREST),
            (vk::Filter::LINEAR, vk::SamplerMipmapMode::LINEAR),
        ]
        .into_iter()
        .enumerate()
        {
            let info = vk::SamplerCreateInfo::default()
                .mag_filter(filter)
                .min_filter(filter)
                .mipmap_mode(mipmap)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .max_lod(vk::LOD_CLAMP_NONE);
            // SAFETY: valid create info; destroyed in Drop.
            graph.samplers[i] = unsafe { ctx.device.create_sampler(&info, None)? };
        }
        for (id, base, count) in ranges {
            let (raw, desc) = (graph.image_raw(id), graph.image_desc(id));
            // SAFETY: the image is sampled (validated usage), the range lies within its mip
            // chain (validated); destroyed in Drop.
            let view = unsafe { create_view(&ctx.device, raw, &desc, base, count)? };
            graph.range_views.insert((id, base, count), view);
        }
        let pipelines = super::pass::create_pipelines(
            ctx,
            self.passes
                .iter()
                .map(|p| (p.name.as_str(), p.program.as_ref())),
        )?;
        let mut scope = 0;
        for ((decl, (first, steady)), pipeline) in
            self.passes.into_iter().zip(barriers).zip(pipelines)
        {
            let pass = CompiledPass {
                pipeline,
                label: CString::new(decl.name.replace('\0', " ")).unwrap_or_default(),
                first: BarrierBatch::new(&graph, &first),
                steady: BarrierBatch::new(&graph, &steady),
                scope: (!decl.on_demand).then(|| {
                    scope += 1;
                    scope - 1
                }),
                decl,
            };
            graph.passes.push(pass);
        }
        Ok(graph)
    }
}

impl CompiledGraph {
    /// Records, submits and waits for one frame of this graph (set-up work such as a
    /// reduction computed once per cloud, or tests).
    pub fn run_once(&mut self, ctx: &Arc<Context>) -> Result<()> {
        let mut frames = crate::gpu::FrameRing::new(ctx, 1, false)?;
        let slot = frames.advance()?;
        let cmd = frames.begin()?;
        self.record(cmd, slot, true);
        frames.end()?;
        frames.submit(None, None)?;
        frames.wait(slot)
    }

    fn image_slot(&self, id: ImageId) -> &ImageSlot {
        &self.images[id.0 as usize].1
    }

    pub(super) fn image_raw(&self, id: ImageId) -> vk::Image {
        match self.image_slot(id) {
            ImageSlot::Owned(i) => i.raw,
            ImageSlot::Imported(i) => i.raw,
            ImageSlot::External { raw, .. } => *raw,
            ImageSlot::Unused(_) => vk::Image::null(),
        }
    }

    pub(super) fn image_desc(&self, id: ImageId) -> ImageDesc {
        match self.image_slot(id) {
            ImageSlot::Owned(i) => i.desc,
            ImageSlot::Imported(i) => i.desc,
            ImageSlot::External { desc, .. } | ImageSlot::Unused(desc) => *desc,
        }
    }

    /// The view of mip levels `base..base + count` of `id`: one level, the whole chain or a
    /// range declared as sampled by some pass.
    pub(super) fn view(&self, id: ImageId, base: u32, count: u32) -> vk::ImageView {
        let levels = self.image_desc(id).mip_levels;
        match self.image_slot(id) {
            ImageSlot::External { view, .. } => Some(*view),
            ImageSlot::Owned(i) => pick_view(i.view, &i.mip_views, levels, base, count),
            ImageSlot::Imported(i) => pick_view(i.view, &i.mip_views, levels, base, count),
            ImageSlot::Unused(_) => None,
        }
        .or_else(|| self.range_views.get(&(id, base, count)).copied())
        .unwrap_or_else(|| {
            panic!(
                "no view of mips {base}..{} of '{}': declare exactly that range as Sampled",
                base + count,
                self.images[id.0 as usize].0
            )
        })
    }

    pub(super) fn buffer_raw(&self, id: BufferId) -> (vk::Buffer, u64) {
        match &self.buffers[id.0 as usize].1 {
            BufferSlot::Owned(b) => (b.raw, b.size),
            BufferSlot::Imported(b) => (b.raw, b.size),
            BufferSlot::External { raw, size, .. } => (*raw, *size),
            BufferSlot::Unused(size) => (vk::Buffer::null(), *size),
        }
    }

    fn batches(&mut self) -> impl Iterator<Item = &mut BarrierBatch> {
        self.passes
            .iter_mut()
            .flat_map(|p| [&mut p.first, &mut p.steady])
    }

    /// Binds this frame's swapchain image (and its view) to an external image.
    pub fn bind_external(&mut self, id: ImageId, image: vk::Image, image_view: vk::ImageView) {
        if let ImageSlot::External { raw, view, .. } = &mut self.images[id.0 as usize].1 {
            *raw = image;
            *view = image_view;
            self.batches().for_each(|b| b.patch_image(id, image));
        }
    }

    /// Binds this frame's buffer to an external buffer (the frame slot's uniforms). Panics
    /// when `buffer` is smaller than declared or lacks the declared usage.
    pub fn bind_external_buffer(&mut self, id: BufferId, buffer: &Buffer) {
        let (name, slot) = &mut self.buffers[id.0 as usize];
        if let BufferSlot::External { size, usage, raw } = slot {
            assert!(
                buffer.size >= *size && buffer.usage.contains(*usage),
                "external buffer '{name}' needs {size} bytes with usage {usage:?}"
            );
            *raw = buffer.raw;
            let raw = *raw;
            self.batches().for_each(|b| b.patch_buffer(id, raw));
        }
    }

    /// Panics naming the first external image or buffer that was never bound.
    pub(super) fn check_externals_bound(&self) {
        for (name, slot) in &self.images {
            if let ImageSlot::External { raw, .. } = slot {
                assert!(
                    *raw != vk::Image::null(),
                    "external image '{name}' is not bound"
                );
            }
        }
        for (name, slot) in &self.buffers {
            if let BufferSlot::External { raw, .. } = slot {
                assert!(
                    *raw != vk::Buffer::null(),
                    "external buffer '{name}' is not bound"
                );
            }
        }
    }

    /// The timestamp profiler (one scope per regular pass).
    pub fn profiler(&mut self) -> &mut Profiler {
        &mut self.profiler
    }

    /// Names of the timed passes in execution order.
    pub fn pass_names(&self) -> Vec<String> {
        self.passes
            .iter()
            .filter(|p| !p.decl.on_demand)
            .map(|p| p.decl.name.clone())
            .collect()
    }
}

fn pick_view(
    whole: vk::ImageView,
    mips: &[vk::ImageView],
    levels: u32,
    base: u32,
    count: u32,
) -> Option<vk::ImageView> {
    if count == 1 {
        mips.get(base as usize).copied()
    } else if base == 0 && count == levels && whole != vk::ImageView::null() {
        Some(whole)
    } else {
        None
    }
}

impl Drop for CompiledGraph {
    fn drop(&mut self) {
        // SAFETY: the owner waited for the frames using the graph; null handles are ignored.
        unsafe {
            for s in self.samplers {
                self.ctx.device.destroy_sampler(s, None);
            }
            for (_, v) in self.range_views.drain() {
                self.ctx.device.destroy_image_view(v, None);
            }
        }
    }
}

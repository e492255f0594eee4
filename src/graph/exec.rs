//! Compiling a `GraphBuilder` (validation, transient allocation, barrier derivation, timestamp
//! scopes) and recording the compiled graph into a command buffer.

use std::collections::HashMap;
use std::ffi::CString;
use std::fmt::Write as _;
use std::sync::Arc;

use anyhow::{anyhow, bail, Result};
use ash::vk;

use super::sync::{apply, Access, SubState, Transition};
use super::{
    Attachment, BufferId, BufferSource, GraphBuilder, ImageId, ImageSource, Load, PassDecl,
    Subresource,
};
use crate::gpu::{Buffer, Context, Image, ImageDesc, Pipeline, Profiler};

/// A barrier on one subresource (one image mip or one buffer), resolved to handles at record time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Barrier {
    pub target: BarrierTarget,
    pub transition: Transition,
}

/// What a barrier applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BarrierTarget {
    Image { id: ImageId, mip: u32 },
    Buffer(BufferId),
}

enum ImageSlot {
    Owned(Image),
    Imported(Arc<Image>),
    External {
        desc: ImageDesc,
        raw: vk::Image,
        view: vk::ImageView,
    },
}

enum BufferSlot {
    Owned(Buffer),
    Imported(Arc<Buffer>),
}

struct CompiledPass {
    decl: PassDecl,
    label: CString,
    /// Barriers before the pass in the first frame (everything starts undefined).
    first: Vec<Barrier>,
    /// Barriers before the pass in every later frame.
    steady: Vec<Barrier>,
    /// Index of the pass's timestamp scope (regular passes only).
    scope: Option<usize>,
}

/// The per-frame state of every subresource: images per mip, then buffers.
#[derive(Clone, PartialEq)]
struct States {
    images: Vec<Vec<SubState>>,
    buffers: Vec<SubState>,
}

/// An executable graph: resources allocated, barriers derived, scopes assigned.
pub struct CompiledGraph {
    ctx: Arc<Context>,
    images: Vec<(String, ImageSlot)>,
    buffers: Vec<(String, BufferSlot)>,
    passes: Vec<CompiledPass>,
    profiler: Profiler,
    nearest: vk::Sampler,
    first_frame: bool,
}

/// Resource kinds that carry their state into the next frame.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Carry {
    /// Contents discarded: the next frame starts from UNDEFINED but waits on this frame's use.
    Discard,
    /// Contents and layout kept.
    Keep,
    /// Re-acquired every frame (swapchain): UNDEFINED, ordered after the acquire semaphore.
    Acquired,
}

fn image_carry(source: &ImageSource) -> Carry {
    match source {
        ImageSource::Transient(_) => Carry::Discard,
        ImageSource::History(_) | ImageSource::Imported(_) => Carry::Keep,
        ImageSource::External(_) => Carry::Acquired,
    }
}

fn next_frame_state(s: SubState, carry: Carry) -> SubState {
    match carry {
        Carry::Keep => s,
        Carry::Discard => SubState {
            layout: vk::ImageLayout::UNDEFINED,
            ..s
        },
        Carry::Acquired => SubState {
            write_stages: vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
            ..SubState::UNDEFINED
        },
    }
}

/// Validates the declarations and derives barriers; pure CPU (no device needed).
pub(crate) fn derive(builder: &GraphBuilder) -> Result<Vec<(Vec<Barrier>, Vec<Barrier>)>> {
    validate(builder)?;
    let initial = States {
        images: builder
            .images
            .iter()
            .map(|r| {
                let init = if image_carry(&r.source) == Carry::Acquired {
                    next_frame_state(SubState::UNDEFINED, Carry::Acquired)
                } else {
                    SubState::UNDEFINED
                };
                vec![init; r.desc().mip_levels as usize]
            })
            .collect(),
        buffers: vec![SubState::UNDEFINED; builder.buffers.len()],
    };
    let (first, mut end) = simulate(builder, initial);
    let carries: Vec<Carry> = builder
        .images
        .iter()
        .map(|r| image_carry(&r.source))
        .collect();
    let mut steady = Vec::new();
    // Iterate to the steady state (read-only resources accumulate reader stages once).
    for _ in 0..4 {
        let start = States {
            images: end
                .images
                .iter()
                .zip(&carries)
                .map(|(mips, c)| mips.iter().map(|s| next_frame_state(*s, *c)).collect())
                .collect(),
            buffers: end.buffers.clone(),
        };
        let (barriers, next_end) = simulate(builder, start);
        steady = barriers;
        if next_end == end {
            break;
        }
        end = next_end;
    }
    Ok(first.into_iter().zip(steady).collect())
}

fn simulate(builder: &GraphBuilder, mut states: States) -> (Vec<Vec<Barrier>>, States) {
    let mut all = Vec::with_capacity(builder.passes.len());
    for pass in &builder.passes {
        let mut barriers = Vec::new();
        for (sub, access) in &pass.uses {
            match *sub {
                Subresource::Image { id, base, count } => {
                    for mip in base..base + count {
                        let s = &mut states.images[id.0 as usize][mip as usize];
                        if let Some(transition) = apply(s, *access, true) {
                            barriers.push(Barrier {
                                target: BarrierTarget::Image { id, mip },
                                transition,
                            });
                        }
                    }
                }
                Subresource::Buffer(id) => {
                    let s = &mut states.buffers[id.0 as usize];
                    if let Some(transition) = apply(s, *access, false) {
                        barriers.push(Barrier {
                            target: BarrierTarget::Buffer(id),
                            transition,
                        });
                    }
                }
            }
        }
        all.push(barriers);
    }
    (all, states)
}

fn validate(builder: &GraphBuilder) -> Result<()> {
    let mut seen_on_demand = false;
    for pass in &builder.passes {
        if pass.on_demand {
            seen_on_demand = true;
        } else if seen_on_demand {
            bail!(
                "pass '{}' follows an on-demand pass; on-demand passes must come last",
                pass.name
            );
        }
        if pass.on_demand {
            // Their state must not leak into frames that skip them: only transient images
            // (discarded each frame) and buffers (no layouts) may be touched.
            for (sub, _) in &pass.uses {
                if let Subresource::Image { id, .. } = sub {
                    let res = &builder.images[id.0 as usize];
                    if !matches!(res.source, ImageSource::Transient(_)) {
                        bail!(
                            "on-demand pass '{}' uses '{}', which is not transient",
                            pass.name,
                            res.name
                        );
                    }
                }
            }
        }
        let mut seen: HashMap<Subresource, Access> = HashMap::new();
        for (sub, access) in &pass.uses {
            match *sub {
                Subresource::Image { id, base, count } => {
                    let res = builder
                        .images
                        .get(id.0 as usize)
                        .ok_or_else(|| anyhow!("pass '{}': unknown image {id:?}", pass.name))?;
                    let levels = res.desc().mip_levels;
                    if count == 0 || base + count > levels {
                        bail!(
                            "pass '{}': mips {base}..{} of '{}' (has {levels})",
                            pass.name,
                            base + count,
                            res.name
                        );
                    }
                }
                Subresource::Buffer(id) => {
                    if id.0 as usize >= builder.buffers.len() {
                        bail!("pass '{}': unknown buffer {id:?}", pass.name);
                    }
                }
            }
            if let Some(prev) = seen.insert(*sub, *access) {
                if prev != *access {
                    bail!(
                        "pass '{}' declares {sub:?} twice ({prev:?} and {access:?})",
                        pass.name
                    );
                }
            }
        }
        let extents: Vec<(u32, u32)> = pass
            .colors
            .iter()
            .chain(&pass.depth)
            .map(|a| builder.desc(a.image).level_extent(a.mip))
            .collect();
        if extents.windows(2).any(|w| w[0] != w[1]) {
            bail!(
                "pass '{}': attachments differ in size {extents:?}",
                pass.name
            );
        }
    }
    Ok(())
}

impl GraphBuilder {
    /// Removes passes whose results nothing uses and returns their names. A pass is kept when
    /// it is on demand, presents or hands data to the host, writes a resource that outlives
    /// the frame (imported, history, external), or writes something a kept pass reads (an
    /// attachment loaded with `Load::Load` is read too).
    pub fn cull(&mut self) -> Vec<String> {
        let persistent_image =
            |id: ImageId| !matches!(self.images[id.0 as usize].source, ImageSource::Transient(_));
        let persistent_buffer = |id: BufferId| {
            matches!(
                self.buffers[id.0 as usize].source,
                BufferSource::Imported(_)
            )
        };
        let mut needed: std::collections::HashSet<(bool, u32, u32)> = Default::default();
        let key = |sub: &Subresource| -> Vec<(bool, u32, u32)> {
            match *sub {
                Subresource::Image { id, base, count } => {
                    (base..base + count).map(|m| (true, id.0, m)).collect()
                }
                Subresource::Buffer(id) => vec![(false, id.0, 0)],
            }
        };
        let mut live = vec![false; self.passes.len()];
        for (i, pass) in self.passes.iter().enumerate().rev() {
            let effect = pass.on_demand
                || pass.uses.is_empty()
                || pass.uses.iter().any(|(sub, access)| {
                    let writes = access.info().writes;
                    matches!(access, Access::Present | Access::HostRead)
                        || (writes
                            && match *sub {
                                Subresource::Image { id, .. } => persistent_image(id),
                                Subresource::Buffer(id) => persistent_buffer(id),
                            })
                        || (writes && key(sub).iter().any(|k| needed.contains(k)))
                });
            if !effect {
                continue;
            }
            live[i] = true;
            let loaded: Vec<(ImageId, u32)> = pass
                .colors
                .iter()
                .chain(&pass.depth)
                .filter(|a| a.load == Load::Load)
                .map(|a| (a.image, a.mip))
                .collect();
            for (sub, access) in &pass.uses {
                let attachment =
                    matches!(access, Access::ColorAttachment | Access::DepthAttachment);
                let reads = !access.info().writes
                    || matches!(access, Access::StorageReadWrite(_))
                    || (attachment
                        && matches!(*sub, Subresource::Image { id, base, .. } if loaded.contains(&(id, base))));
                if reads {
                    needed.extend(key(sub));
                }
            }
        }
        let mut culled = Vec::new();
        let mut index = 0;
        self.passes.retain(|p| {
            index += 1;
            if !live[index - 1] {
                culled.push(p.name.clone());
            }
            live[index - 1]
        });
        culled
    }

    /// Validates, culls unused passes, derives barriers, allocates transient resources and
    /// timestamp scopes.
    pub fn compile(mut self, ctx: &Arc<Context>) -> Result<CompiledGraph> {
        self.cull();
        let barriers = derive(&self)?;
        let images = self
            .images
            .into_iter()
            .map(|r| {
                let slot = match r.source {
                    ImageSource::Transient(d) | ImageSource::History(d) => {
                        ImageSlot::Owned(Image::new(ctx, &r.name, d)?)
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
            .map(|r| {
                let slot = match r.source {
                    BufferSource::Transient { size, usage } => BufferSlot::Owned(Buffer::new(
                        ctx,
                        &r.name,
                        size,
                        usage,
                        gpu_allocator::MemoryLocation::GpuOnly,
                    )?),
                    BufferSource::Imported(b) => BufferSlot::Imported(b),
                };
                Ok((r.name, slot))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut scope_names = Vec::new();
        let passes = self
            .passes
            .into_iter()
            .zip(barriers)
            .map(|(decl, (first, steady))| {
                let scope = (!decl.on_demand).then(|| {
                    scope_names.push(decl.name.clone());
                    scope_names.len() - 1
                });
                CompiledPass {
                    label: CString::new(decl.name.replace('\0', " ")).unwrap_or_default(),
                    decl,
                    first,
                    steady,
                    scope,
                }
            })
            .collect();
        let sampler = |filter: vk::Filter| {
            let info = vk::SamplerCreateInfo::default()
                .mag_filter(filter)
                .min_filter(filter)
                .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .max_lod(vk::LOD_CLAMP_NONE);
            // SAFETY: valid create info; destroyed in Drop.
            unsafe { ctx.device.create_sampler(&info, None) }
        };
        Ok(CompiledGraph {
            ctx: ctx.clone(),
            profiler: Profiler::new(ctx, scope_names)?,
            images,
            buffers,
            passes,
            nearest: sampler(vk::Filter::NEAREST)?,
            first_frame: true,
        })
    }

    /// The derived schedule (passes, accesses, barriers) without a device, for tests and
    /// `--dump-graph`.
    pub fn schedule(&self) -> Result<String> {
        let barriers = derive(self)?;
        let names = |t: &BarrierTarget| match *t {
            BarrierTarget::Image { id, mip } => {
                format!("{}[mip {mip}]", self.images[id.0 as usize].name)
            }
            BarrierTarget::Buffer(id) => self.buffers[id.0 as usize].name.clone(),
        };
        let mut s = String::new();
        for (i, (pass, (_, steady))) in self.passes.iter().zip(&barriers).enumerate() {
            let kind = if pass.on_demand { " (on demand)" } else { "" };
            writeln!(s, "{i}: {}{kind}", pass.name).expect("fmt");
            for (sub, access) in &pass.uses {
                let what = match *sub {
                    Subresource::Image { id, base, count } => format!(
                        "{} mips {base}..{}",
                        self.images[id.0 as usize].name,
                        base + count
                    ),
                    Subresource::Buffer(id) => self.buffers[id.0 as usize].name.clone(),
                };
                writeln!(s, "    {access:?} {what}").expect("fmt");
            }
            for b in steady {
                let t = b.transition;
                writeln!(
                    s,
                    "    barrier {}: {:?}/{:?} -> {:?}/{:?}, {:?} -> {:?}",
                    names(&b.target),
                    t.src_stages,
                    t.src_access,
                    t.dst_stages,
                    t.dst_access,
                    t.old_layout,
                    t.new_layout
                )
                .expect("fmt");
            }
        }
        Ok(s)
    }

    /// Derived barriers per pass (steady state), for tests.
    pub fn barriers(&self) -> Result<Vec<Vec<Barrier>>> {
        Ok(derive(self)?.into_iter().map(|(_, s)| s).collect())
    }

    /// Derived barriers per pass in the first frame, for tests.
    pub fn first_frame_barriers(&self) -> Result<Vec<Vec<Barrier>>> {
        Ok(derive(self)?.into_iter().map(|(f, _)| f).collect())
    }
}

/// Bound to a pass while it records: resolves handles and offers the few commands passes use.
pub struct PassContext<'a> {
    pub ctx: &'a Context,
    pub cmd: vk::CommandBuffer,
    graph: &'a CompiledGraph,
    /// Render area of the pass's attachments (zero for compute/transfer passes).
    pub extent: vk::Extent2D,
}

/// One descriptor of a push-descriptor set.
#[derive(Clone, Copy, Debug)]
pub enum Descriptor {
    /// Storage (or uniform-like storage) buffer.
    Buffer(u32, BufferId),
    /// Storage image at one mip level (GENERAL layout).
    StorageImage(u32, ImageId, u32),
    /// Combined image sampler of one mip level, nearest filtering.
    Sampled(u32, ImageId, u32),
}

impl PassContext<'_> {
    pub fn image(&self, id: ImageId) -> vk::Image {
        self.graph.image_raw(id)
    }

    pub fn desc(&self, id: ImageId) -> ImageDesc {
        self.graph.image_desc(id)
    }

    pub fn buffer(&self, id: BufferId) -> vk::Buffer {
        self.graph.buffer_raw(id).0
    }

    /// Binds `pipeline` and pushes its descriptors.
    pub fn bind(&self, pipeline: &Pipeline, descriptors: &[Descriptor]) {
        let d = &self.ctx.device;
        enum Info {
            Buffer([vk::DescriptorBufferInfo; 1]),
            Image([vk::DescriptorImageInfo; 1]),
        }
        let image = |id: ImageId, mip: u32, layout: vk::ImageLayout, sampler: vk::Sampler| {
            Info::Image([vk::DescriptorImageInfo::default()
                .image_view(self.graph.view(id, mip))
                .sampler(sampler)
                .image_layout(layout)])
        };
        let infos: Vec<(u32, vk::DescriptorType, Info)> = descriptors
            .iter()
            .map(|desc| match *desc {
                Descriptor::Buffer(binding, id) => {
                    let (raw, size) = self.graph.buffer_raw(id);
                    let info = vk::DescriptorBufferInfo::default().buffer(raw).range(size);
                    (
                        binding,
                        vk::DescriptorType::STORAGE_BUFFER,
                        Info::Buffer([info]),
                    )
                }
                Descriptor::StorageImage(binding, id, mip) => (
                    binding,
                    vk::DescriptorType::STORAGE_IMAGE,
                    image(id, mip, vk::ImageLayout::GENERAL, vk::Sampler::null()),
                ),
                Descriptor::Sampled(binding, id, mip) => (
                    binding,
                    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                    image(
                        id,
                        mip,
                        vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                        self.graph.nearest,
                    ),
                ),
            })
            .collect();
        let writes: Vec<_> = infos
            .iter()
            .map(|(binding, ty, info)| {
                let w = vk::WriteDescriptorSet::default()
                    .dst_binding(*binding)
                    .descriptor_type(*ty);
                match info {
                    Info::Buffer(b) => w.buffer_info(b),
                    Info::Image(i) => w.image_info(i),
                }
            })
            .collect();
        // SAFETY: the command buffer is recording; descriptors match the pipeline's layout.
        unsafe {
            d.cmd_bind_pipeline(self.cmd, pipeline.bind_point, pipeline.raw);
            if !writes.is_empty() {
                self.ctx.push_descriptor.cmd_push_descriptor_set(
                    self.cmd,
                    pipeline.bind_point,
                    pipeline.layout,
                    0,
                    &writes,
                );
            }
        }
    }

    /// Pushes constants (at most `PUSH_CONSTANT_BYTES`) to every stage of `pipeline`.
    pub fn push(&self, pipeline: &Pipeline, bytes: &[u8]) {
        // SAFETY: recording; range within the layout's push-constant range.
        unsafe {
            self.ctx
                .device
                .cmd_push_constants(self.cmd, pipeline.layout, pipeline.stages, 0, bytes)
        };
    }

    pub fn draw(&self, vertices: u32, instances: u32) {
        // SAFETY: recording inside the pass's rendering scope with a bound pipeline.
        unsafe {
            self.ctx
                .device
                .cmd_draw(self.cmd, vertices, instances, 0, 0)
        };
    }

    pub fn draw_indexed(&self, index_buffer: BufferId, indices: u32) {
        // SAFETY: recording; the index buffer was declared with Access::IndexRead.
        unsafe {
            self.ctx.device.cmd_bind_index_buffer(
                self.cmd,
                self.buffer(index_buffer),
                0,
                vk::IndexType::UINT32,
            );
            self.ctx
                .device
                .cmd_draw_indexed(self.cmd, indices, 1, 0, 0, 0);
        }
    }

    pub fn dispatch(&self, x: u32, y: u32, z: u32) {
        // SAFETY: recording outside rendering with a bound compute pipeline.
        unsafe { self.ctx.device.cmd_dispatch(self.cmd, x, y, z) };
    }

    /// Scales mip `src_mip` of `src` onto mip `dst_mip` of `dst` (declared TransferSrc /
    /// TransferDst on those levels). Also presents to swapchain images (mip 0 to mip 0).
    pub fn blit(&self, src: ImageId, src_mip: u32, dst: ImageId, dst_mip: u32) {
        let corner = |d: ImageDesc, mip: u32| {
            let (w, h) = d.level_extent(mip);
            [
                vk::Offset3D::default(),
                vk::Offset3D {
                    x: w as i32,
                    y: h as i32,
                    z: 1,
                },
            ]
        };
        let region = vk::ImageBlit::default()
            .src_subresource(color_layers(src_mip))
            .src_offsets(corner(self.desc(src), src_mip))
            .dst_subresource(color_layers(dst_mip))
            .dst_offsets(corner(self.desc(dst), dst_mip));
        // SAFETY: layouts match the declared transfer accesses.
        unsafe {
            self.ctx.device.cmd_blit_image(
                self.cmd,
                self.image(src),
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                self.image(dst),
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
                vk::Filter::NEAREST,
            )
        };
    }

    /// Copies one mip level between two images of the same format and size (the ping-pong
    /// "copy pass" that fills the levels an image is missing).
    pub fn copy_mip(&self, src: ImageId, dst: ImageId, mip: u32) {
        let (width, height) = self.desc(src).level_extent(mip);
        let region = vk::ImageCopy::default()
            .src_subresource(color_layers(mip))
            .dst_subresource(color_layers(mip))
            .extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            });
        // SAFETY: the pass declared TransferSrc/TransferDst on `mip` of both images.
        unsafe {
            self.ctx.device.cmd_copy_image(
                self.cmd,
                self.image(src),
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                self.image(dst),
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            )
        };
    }

    /// Clears one mip level of a color image (declared TransferDst).
    pub fn clear(&self, image: ImageId, mip: u32, color: [f32; 4]) {
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: mip,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        };
        // SAFETY: the pass declared TransferDst on `mip`.
        unsafe {
            self.ctx.device.cmd_clear_color_image(
                self.cmd,
                self.image(image),
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &vk::ClearColorValue { float32: color },
                &[range],
            )
        };
    }

    /// Copies mip `mip` of `image` (tightly packed) into `buffer` at offset 0.
    pub fn copy_image_to_buffer(&self, image: ImageId, mip: u32, buffer: BufferId) {
        let desc = self.desc(image);
        let (width, height) = desc.level_extent(mip);
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: desc.aspect(),
                mip_level: mip,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            });
        // SAFETY: the pass declared TransferSrc on the image and TransferDst on the buffer.
        unsafe {
            self.ctx.device.cmd_copy_image_to_buffer(
                self.cmd,
                self.image(image),
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                self.buffer(buffer),
                &[region],
            )
        };
    }
}

fn color_layers(mip: u32) -> vk::ImageSubresourceLayers {
    vk::ImageSubresourceLayers {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        mip_level: mip,
        base_array_layer: 0,
        layer_count: 1,
    }
}

impl CompiledGraph {
    fn image_slot(&self, id: ImageId) -> &ImageSlot {
        &self.images[id.0 as usize].1
    }

    fn image_raw(&self, id: ImageId) -> vk::Image {
        match self.image_slot(id) {
            ImageSlot::Owned(i) => i.raw,
            ImageSlot::Imported(i) => i.raw,
            ImageSlot::External { raw, .. } => *raw,
        }
    }

    fn image_desc(&self, id: ImageId) -> ImageDesc {
        match self.image_slot(id) {
            ImageSlot::Owned(i) => i.desc,
            ImageSlot::Imported(i) => i.desc,
            ImageSlot::External { desc, .. } => *desc,
        }
    }

    fn view(&self, id: ImageId, mip: u32) -> vk::ImageView {
        match self.image_slot(id) {
            ImageSlot::Owned(i) => i.mip_views[mip as usize],
            ImageSlot::Imported(i) => i.mip_views[mip as usize],
            ImageSlot::External { view, .. } => *view,
        }
    }

    fn buffer_raw(&self, id: BufferId) -> (vk::Buffer, u64) {
        match &self.buffers[id.0 as usize].1 {
            BufferSlot::Owned(b) => (b.raw, b.size),
            BufferSlot::Imported(b) => (b.raw, b.size),
        }
    }

    /// Binds this frame's swapchain image (and its view) to an external image.
    pub fn bind_external(&mut self, id: ImageId, image: vk::Image, image_view: vk::ImageView) {
        if let ImageSlot::External { raw, view, .. } = &mut self.images[id.0 as usize].1 {
            *raw = image;
            *view = image_view;
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

    /// Records the whole frame into `cmd` (which must be recording). On-demand passes are
    /// recorded only when `on_demand` is set.
    pub fn record(&mut self, cmd: vk::CommandBuffer, on_demand: bool) {
        self.profiler.reset(cmd);
        let first = self.first_frame;
        for pass in &self.passes {
            if pass.decl.on_demand && !on_demand {
                continue;
            }
            self.ctx.begin_label(cmd, &pass.label);
            self.emit_barriers(cmd, if first { &pass.first } else { &pass.steady });
            if let Some(scope) = pass.scope {
                self.profiler.stamp(cmd, scope, false);
            }
            let extent = self.begin_rendering(cmd, &pass.decl);
            (pass.decl.record)(&PassContext {
                ctx: &self.ctx,
                cmd,
                graph: self,
                extent,
            });
            if extent.width > 0 {
                // SAFETY: matches begin_rendering above.
                unsafe { self.ctx.device.cmd_end_rendering(cmd) };
            }
            if let Some(scope) = pass.scope {
                self.profiler.stamp(cmd, scope, true);
            }
            self.ctx.end_label(cmd);
        }
        self.first_frame = false;
    }

    fn begin_rendering(&self, cmd: vk::CommandBuffer, decl: &PassDecl) -> vk::Extent2D {
        let Some(first) = decl.colors.first().or(decl.depth.as_ref()) else {
            return vk::Extent2D::default();
        };
        let (width, height) = self.image_desc(first.image).level_extent(first.mip);
        let extent = vk::Extent2D { width, height };
        let attachment = |a: &Attachment, layout: vk::ImageLayout, depth: bool| {
            let (load_op, clear) = match a.load {
                Load::Clear(c) => (
                    vk::AttachmentLoadOp::CLEAR,
                    if depth {
                        vk::ClearValue {
                            depth_stencil: vk::ClearDepthStencilValue {
                                depth: c[0],
                                stencil: 0,
                            },
                        }
                    } else {
                        vk::ClearValue {
                            color: vk::ClearColorValue { float32: c },
                        }
                    },
                ),
                Load::Load => (vk::AttachmentLoadOp::LOAD, vk::ClearValue::default()),
                Load::DontCare => (vk::AttachmentLoadOp::DONT_CARE, vk::ClearValue::default()),
            };
            vk::RenderingAttachmentInfo::default()
                .image_view(self.view(a.image, a.mip))
                .image_layout(layout)
                .load_op(load_op)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(clear)
        };
        let colors: Vec<_> = decl
            .colors
            .iter()
            .map(|a| attachment(a, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, false))
            .collect();
        let depth = decl
            .depth
            .as_ref()
            .map(|a| attachment(a, vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL, true));
        let area = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent,
        };
        let mut info = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1)
            .color_attachments(&colors);
        if let Some(d) = depth.as_ref() {
            info = info.depth_attachment(d);
        }
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: width as f32,
            height: height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        // SAFETY: recording; attachments were transitioned by the derived barriers.
        unsafe {
            self.ctx.device.cmd_begin_rendering(cmd, &info);
            self.ctx.device.cmd_set_viewport(cmd, 0, &[viewport]);
            self.ctx.device.cmd_set_scissor(cmd, 0, &[area]);
        }
        extent
    }

    fn emit_barriers(&self, cmd: vk::CommandBuffer, barriers: &[Barrier]) {
        if barriers.is_empty() {
            return;
        }
        let mut image_barriers = Vec::new();
        let mut buffer_barriers = Vec::new();
        for b in barriers {
            let t = b.transition;
            match b.target {
                BarrierTarget::Image { id, mip } => {
                    let desc = self.image_desc(id);
                    let range = vk::ImageSubresourceRange {
                        aspect_mask: desc.aspect(),
                        base_mip_level: mip,
                        level_count: 1,
                        base_array_layer: 0,
                        layer_count: 1,
                    };
                    image_barriers.push(
                        vk::ImageMemoryBarrier2::default()
                            .src_stage_mask(t.src_stages)
                            .src_access_mask(t.src_access)
                            .dst_stage_mask(t.dst_stages)
                            .dst_access_mask(t.dst_access)
                            .old_layout(t.old_layout)
                            .new_layout(t.new_layout)
                            .image(self.image_raw(id))
                            .subresource_range(range),
                    );
                }
                BarrierTarget::Buffer(id) => {
                    let (raw, size) = self.buffer_raw(id);
                    buffer_barriers.push(
                        vk::BufferMemoryBarrier2::default()
                            .src_stage_mask(t.src_stages)
                            .src_access_mask(t.src_access)
                            .dst_stage_mask(t.dst_stages)
                            .dst_access_mask(t.dst_access)
                            .buffer(raw)
                            .size(size),
                    );
                }
            }
        }
        let dep = vk::DependencyInfo::default()
            .image_memory_barriers(&image_barriers)
            .buffer_memory_barriers(&buffer_barriers);
        // SAFETY: recording outside a rendering scope.
        unsafe { self.ctx.device.cmd_pipeline_barrier2(cmd, &dep) };
    }
}

impl Drop for CompiledGraph {
    fn drop(&mut self) {
        // SAFETY: the owner waited for the frames using the graph.
        unsafe {
            self.ctx.device.destroy_sampler(self.nearest, None);
        }
    }
}

//! Recording a compiled graph: barriers before each pass, dynamic rendering for passes with
//! attachments, timestamps and labels, and `PassContext`, the only way passes record
//! commands. Every command checks that the pass declared the access it performs.

use ash::vk;

use std::fmt;

use super::bind::{fold_groups, Bind, Resource};
use super::compile::{BarrierBatch, CompiledGraph};
use super::{
    Access, Attachment, BufferId, BufferRange, ImageId, Load, PassDecl, Subresource,
    MAX_COLOR_ATTACHMENTS, MAX_DESCRIPTORS,
};
use crate::gpu::{Context, ImageDesc, Pipeline};

impl CompiledGraph {
    /// Records the whole frame into `cmd` (which must be recording), timing it in frame slot
    /// `slot`'s query pool (`slot < frames_in_flight` of `compile_frames`; the slot's previous
    /// frame must have finished and been collected). On-demand passes are recorded only when `on_demand` is set.
    /// Allocates nothing: barriers were resolved at compile time and commands are built in
    /// fixed-size arrays.
    pub fn record(&mut self, cmd: vk::CommandBuffer, slot: usize, on_demand: bool) {
        assert!(
            slot < self.profiler.slots(),
            "frame slot {slot} of a graph compiled for {} frames in flight",
            self.profiler.slots()
        );
        self.check_externals_bound();
        self.profiler.reset(cmd, slot);
        let first = self.first_frame;
        // Scopes follow each other: a regular pass's boundary stamp, written before its
        // barriers, ends the previous pass's scope, and the frame ends before the first
        // on-demand pass (validation keeps those last) or after the last pass. The time a
        // pass's barriers wait for earlier work counts to the waiting pass.
        let scopes = self.profiler.scopes_len();
        let mut frame_open = scopes > 0;
        for pass in &self.passes {
            if pass.decl.on_demand && !on_demand {
                continue;
            }
            self.ctx.begin_label(cmd, &pass.label);
            match pass.scope {
                Some(scope) => self.profiler.stamp(cmd, slot, scope),
                None if frame_open => {
                    self.profiler.stamp(cmd, slot, scopes);
                    frame_open = false;
                }
                None => {}
            }
            self.emit_barriers(cmd, if first { &pass.first } else { &pass.steady });
            if let Some(scope) = pass.scope {
                self.profiler.begin_statistics(cmd, slot, scope);
            }
            let extent = self.begin_rendering(cmd, &pass.decl);
            (pass.decl.record)(&PassContext {
                ctx: &self.ctx,
                cmd,
                graph: self,
                pass: &pass.decl,
                pipeline: pass.pipeline.as_deref(),
                extent,
            });
            if extent.width > 0 {
                // SAFETY: matches begin_rendering above.
                unsafe { self.ctx.device.cmd_end_rendering(cmd) };
            }
            if let Some(scope) = pass.scope {
                self.profiler.end_statistics(cmd, slot, scope);
            }
            self.ctx.end_label(cmd);
        }
        if frame_open {
            self.profiler.stamp(cmd, slot, scopes);
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
                .image_view(self.view(a.image, a.mip, 1))
                .image_layout(layout)
                .load_op(load_op)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(clear)
        };
        // At most MAX_COLOR_ATTACHMENTS (validated at compile).
        let mut colors = [vk::RenderingAttachmentInfo::default(); MAX_COLOR_ATTACHMENTS];
        for (info, a) in colors.iter_mut().zip(&decl.colors) {
            *info = attachment(a, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, false);
        }
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
            .color_attachments(&colors[..decl.colors.len()]);
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

    fn emit_barriers(&self, cmd: vk::CommandBuffer, barriers: &BarrierBatch) {
        if barriers.is_empty() {
            return;
        }
        let dep = vk::DependencyInfo::default()
            .image_memory_barriers(&barriers.images)
            .buffer_memory_barriers(&barriers.buffers);
        // SAFETY: recording outside a rendering scope; external handles were patched in by
        // `bind_external`/`bind_external_buffer` (checked bound at the start of `record`).
        unsafe { self.ctx.device.cmd_pipeline_barrier2(cmd, &dep) };
    }
}

/// Which sampler a sampled descriptor uses (both clamp to the edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Sampler {
    /// Nearest texel, nearest mip.
    Nearest,
    /// Bilinear within a mip, linear between mips.
    Linear,
}

/// One descriptor of a push-descriptor set. `PassContext::bind` checks that the pass declared
/// the resource (the levels or bytes bound) with a matching access.
#[derive(Clone, Copy, Debug)]
pub enum Descriptor {
    /// Whole storage buffer (declared `Storage*` or `UniformRead`).
    Buffer(u32, BufferId),
    /// Range of a storage buffer (declared `Storage*` or `UniformRead` on those bytes).
    BufferRange(u32, BufferId, BufferRange),
    /// Whole uniform buffer (`UNIFORM_BUFFER`, declared `UniformRead`).
    Uniform(u32, BufferId),
    /// Storage image at one mip level (GENERAL layout, declared `Storage*`).
    StorageImage(u32, ImageId, u32),
    /// Combined image sampler of one mip level, nearest filtering (declared `Sampled`).
    Sampled(u32, ImageId, u32),
    /// Combined image sampler of mip levels `base..base + count` with `sampler` (declared
    /// `Sampled`). One level, the whole chain, or a range some pass declared exactly.
    SampledMips {
        binding: u32,
        image: ImageId,
        base: u32,
        count: u32,
        sampler: Sampler,
    },
}

/// Bound to a pass while it records: resolves handles and offers every command a pass may
/// record. Each command panics when the pass did not declare the access it performs: that is
/// a programming error in the method, caught by its tests.
pub struct PassContext<'a> {
    pub(crate) ctx: &'a Context,
    pub(crate) cmd: vk::CommandBuffer,
    graph: &'a CompiledGraph,
    pass: &'a PassDecl,
    pub(super) pipeline: Option<&'a Pipeline>,
    /// Render area of the pass's attachments (zero for compute/transfer passes).
    pub extent: vk::Extent2D,
}

fn is_storage(a: Access) -> bool {
    matches!(
        a,
        Access::StorageRead(_) | Access::StorageWrite(_) | Access::StorageReadWrite(_)
    )
}

/// Whether `uses` declares every byte of `range` of `buffer` (of `size` bytes) with an access
/// `ok` accepts.
fn buffer_declared(
    uses: &[(Subresource, Access)],
    buffer: BufferId,
    size: u64,
    range: BufferRange,
    ok: impl Fn(Access) -> bool,
) -> bool {
    let end = range.end().min(size);
    let mut reached = range.offset;
    while reached < end {
        // The furthest end of a declared span that covers `reached`.
        let next = uses
            .iter()
            .filter_map(|(sub, access)| match *sub {
                Subresource::Buffer(id, r) if id == buffer && ok(*access) => {
                    let stop = r.end().min(size);
                    (r.offset <= reached && stop > reached).then_some(stop)
                }
                _ => None,
            })
            .max();
        match next {
            Some(stop) => reached = stop,
            None => return false,
        }
    }
    true
}

/// Whether `uses` declares every level of `base..base + count` of `image` with an access `ok`
/// accepts.
fn mips_declared(
    uses: &[(Subresource, Access)],
    image: ImageId,
    base: u32,
    count: u32,
    ok: impl Fn(Access) -> bool,
) -> bool {
    (base..base + count).all(|mip| {
        uses.iter().any(|(sub, access)| {
            matches!(*sub, Subresource::Image { id, base: b, count: c }
                if id == image && b <= mip && mip < b + c)
                && ok(*access)
        })
    })
}

impl PassContext<'_> {
    pub(super) fn pass_name(&self) -> &str {
        &self.pass.name
    }

    pub fn image(&self, id: ImageId) -> vk::Image {
        self.graph.image_raw(id)
    }

    pub fn desc(&self, id: ImageId) -> ImageDesc {
        self.graph.image_desc(id)
    }

    pub fn buffer(&self, id: BufferId) -> vk::Buffer {
        self.graph.buffer_raw(id).0
    }

    fn check_buffer(
        &self,
        what: impl fmt::Display,
        id: BufferId,
        range: BufferRange,
        needs: impl fmt::Display,
        ok: impl Fn(Access) -> bool,
    ) {
        let size = self.graph.buffer_raw(id).1;
        if !buffer_declared(&self.pass.uses, id, size, range, ok) {
            panic!(
                "pass '{}': {what} uses bytes {range} of buffer '{}' but the pass does not \
                 declare them as {needs}",
                self.pass.name, self.graph.buffers[id.0 as usize].0
            );
        }
    }

    fn check_mips(
        &self,
        what: impl fmt::Display,
        id: ImageId,
        base: u32,
        count: u32,
        needs: impl fmt::Display,
        ok: impl Fn(Access) -> bool,
    ) {
        if !mips_declared(&self.pass.uses, id, base, count, ok) {
            panic!(
                "pass '{}': {what} uses mips {base}..{} of image '{}' but the pass does not \
                 declare them as {needs}",
                self.pass.name,
                base + count,
                self.graph.images[id.0 as usize].0
            );
        }
    }

    /// `check_buffer` for commands that need exactly the access `needs`.
    fn check_buffer_is(&self, what: &str, id: BufferId, range: BufferRange, needs: Access) {
        self.check_buffer(what, id, range, format_args!("{needs:?}"), |a| a == needs);
    }

    fn check_indirect(
        &self,
        what: &str,
        id: BufferId,
        offset: u64,
        count: u32,
        stride: u32,
        bytes: u64,
    ) {
        if count > 0 {
            let size = u64::from(count - 1) * u64::from(stride) + bytes;
            self.check_buffer_is(
                what,
                id,
                BufferRange::new(offset, size),
                Access::IndirectRead,
            );
        }
    }

    /// Binds `pipeline` and pushes its descriptors.
    pub fn bind(&self, pipeline: &Pipeline, descriptors: &[Descriptor]) {
        #[derive(Clone, Copy)]
        enum Info {
            Buffer([vk::DescriptorBufferInfo; 1]),
            Image([vk::DescriptorImageInfo; 1]),
        }
        assert!(
            descriptors.len() <= MAX_DESCRIPTORS,
            "pass '{}': {} descriptors in one bind (at most {MAX_DESCRIPTORS})",
            self.pass.name,
            descriptors.len()
        );
        let buffer = |binding: u32, id: BufferId, range: BufferRange, uniform: bool| {
            let what = format_args!("binding {binding}");
            if uniform {
                self.check_buffer(what, id, range, "UniformRead", |a| {
                    matches!(a, Access::UniformRead(_))
                });
            } else {
                self.check_buffer(what, id, range, "Storage* or UniformRead", |a| {
                    is_storage(a) || matches!(a, Access::UniformRead(_))
                });
            }
            let info = vk::DescriptorBufferInfo::default()
                .buffer(self.graph.buffer_raw(id).0)
                .offset(range.offset)
                .range(range.size);
            let ty = if uniform {
                vk::DescriptorType::UNIFORM_BUFFER
            } else {
                vk::DescriptorType::STORAGE_BUFFER
            };
            (binding, ty, Info::Buffer([info]))
        };
        let sampled = |binding: u32, id: ImageId, base: u32, count: u32, sampler: Sampler| {
            self.check_mips(
                format_args!("binding {binding}"),
                id,
                base,
                count,
                "Sampled",
                |a| matches!(a, Access::Sampled(_)),
            );
            let info = vk::DescriptorImageInfo::default()
                .image_view(self.graph.view(id, base, count))
                .sampler(self.graph.samplers[sampler as usize])
                .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL);
            (
                binding,
                vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
                Info::Image([info]),
            )
        };
        // Fixed-size arrays: binding allocates nothing.
        let unused = (
            0,
            vk::DescriptorType::STORAGE_BUFFER,
            Info::Buffer([vk::DescriptorBufferInfo::default()]),
        );
        let mut infos = [unused; MAX_DESCRIPTORS];
        for (info, desc) in infos.iter_mut().zip(descriptors) {
            *info = match *desc {
                Descriptor::Buffer(binding, id) => buffer(binding, id, BufferRange::WHOLE, false),
                Descriptor::BufferRange(binding, id, range) => buffer(binding, id, range, false),
                Descriptor::Uniform(binding, id) => buffer(binding, id, BufferRange::WHOLE, true),
                Descriptor::StorageImage(binding, id, mip) => {
                    self.check_mips(
                        format_args!("binding {binding}"),
                        id,
                        mip,
                        1,
                        "Storage*",
                        is_storage,
                    );
                    let info = vk::DescriptorImageInfo::default()
                        .image_view(self.graph.view(id, mip, 1))
                        .image_layout(vk::ImageLayout::GENERAL);
                    (
                        binding,
                        vk::DescriptorType::STORAGE_IMAGE,
                        Info::Image([info]),
                    )
                }
                Descriptor::Sampled(binding, id, mip) => {
                    sampled(binding, id, mip, 1, Sampler::Nearest)
                }
                Descriptor::SampledMips {
                    binding,
                    image,
                    base,
                    count,
                    sampler,
                } => sampled(binding, image, base, count, sampler),
            };
        }
        let mut writes = [vk::WriteDescriptorSet::default(); MAX_DESCRIPTORS];
        for (w, (binding, ty, info)) in writes.iter_mut().zip(&infos[..descriptors.len()]) {
            let write = vk::WriteDescriptorSet::default()
                .dst_binding(*binding)
                .descriptor_type(*ty);
            *w = match info {
                Info::Buffer(b) => write.buffer_info(b),
                Info::Image(i) => write.image_info(i),
            };
        }
        let writes = &writes[..descriptors.len()];
        // SAFETY: the command buffer is recording; descriptors match the pipeline's layout.
        unsafe {
            self.ctx
                .device
                .cmd_bind_pipeline(self.cmd, pipeline.bind_point, pipeline.raw);
            if !writes.is_empty() {
                self.ctx.push_descriptor.cmd_push_descriptor_set(
                    self.cmd,
                    pipeline.bind_point,
                    pipeline.layout,
                    0,
                    writes,
                );
            }
        }
    }

    /// Binds `pipeline` and pushes the descriptors of `binds` (declared with
    /// `PassBuilder::binds`).
    pub fn bind_all(&self, pipeline: &Pipeline, binds: &[Bind]) {
        let unused = self.pass.unused;
        let mut descriptors = [Descriptor::Buffer(0, BufferId(0)); MAX_DESCRIPTORS];
        assert!(
            binds.len() <= MAX_DESCRIPTORS,
            "pass '{}': {} bindings (at most {MAX_DESCRIPTORS})",
            self.pass.name,
            binds.len()
        );
        for (d, b) in descriptors.iter_mut().zip(binds) {
            let placeholder = match (b.resource, unused) {
                (Resource::Unused, None) => panic!(
                    "pass '{}': binding {} is unused but the pass did not declare its binds",
                    self.pass.name, b.binding
                ),
                (_, id) => id.unwrap_or(BufferId(0)),
            };
            *d = b.descriptor(placeholder);
        }
        self.bind(pipeline, &descriptors[..binds.len()]);
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

    fn bind_index_buffer(&self, index_buffer: BufferId, bytes: u64) {
        self.check_buffer_is(
            "the index buffer",
            index_buffer,
            BufferRange::new(0, bytes),
            Access::IndexRead,
        );
        // SAFETY: recording; the buffer was declared IndexRead (checked above).
        unsafe {
            self.ctx.device.cmd_bind_index_buffer(
                self.cmd,
                self.buffer(index_buffer),
                0,
                vk::IndexType::UINT32,
            )
        };
    }

    /// Draws `indices` 32-bit indices from `index_buffer` (declared `IndexRead`).
    pub fn draw_indexed(&self, index_buffer: BufferId, indices: u32) {
        self.bind_index_buffer(index_buffer, u64::from(indices) * 4);
        // SAFETY: recording inside the rendering scope; index buffer bound above.
        unsafe {
            self.ctx
                .device
                .cmd_draw_indexed(self.cmd, indices, 1, 0, 0, 0)
        };
    }

    /// `draw_count` draws whose `vk::DrawIndirectCommand`s lie in `args` (declared
    /// `IndirectRead`) from `offset`, `stride` bytes apart.
    pub fn draw_indirect(&self, args: BufferId, offset: u64, draw_count: u32, stride: u32) {
        self.check_indirect("draw_indirect", args, offset, draw_count, stride, 16);
        // SAFETY: recording inside the rendering scope; arguments declared IndirectRead.
        unsafe {
            self.ctx.device.cmd_draw_indirect(
                self.cmd,
                self.buffer(args),
                offset,
                draw_count,
                stride,
            )
        };
    }

    /// Indexed indirect draws (`vk::DrawIndexedIndirectCommand`s in `args`, 32-bit indices in
    /// `index_buffer`, declared `IndirectRead` and `IndexRead`).
    pub fn draw_indexed_indirect(
        &self,
        index_buffer: BufferId,
        args: BufferId,
        offset: u64,
        draw_count: u32,
        stride: u32,
    ) {
        self.bind_index_buffer(index_buffer, 4);
        self.check_indirect(
            "draw_indexed_indirect",
            args,
            offset,
            draw_count,
            stride,
            20,
        );
        // SAFETY: recording inside the rendering scope; buffers declared (checked above).
        unsafe {
            self.ctx.device.cmd_draw_indexed_indirect(
                self.cmd,
                self.buffer(args),
                offset,
                draw_count,
                stride,
            )
        };
    }

    /// Indirect draws whose count (a `u32` at `count_offset` of `count`) is read on the GPU,
    /// at most `max_draws`. Needs `Capabilities::draw_indirect_count`.
    pub fn draw_indirect_count(
        &self,
        args: BufferId,
        offset: u64,
        count: BufferId,
        count_offset: u64,
        max_draws: u32,
        stride: u32,
    ) {
        assert!(
            self.ctx.caps.draw_indirect_count,
            "pass '{}': draw_indirect_count needs the drawIndirectCount feature",
            self.pass.name
        );
        self.check_indirect("draw_indirect_count", args, offset, max_draws, stride, 16);
        self.check_indirect("draw_indirect_count (count)", count, count_offset, 1, 4, 4);
        // SAFETY: recording inside the rendering scope; the feature is enabled (asserted) and
        // both buffers were declared IndirectRead.
        unsafe {
            self.ctx.device.cmd_draw_indirect_count(
                self.cmd,
                self.buffer(args),
                offset,
                self.buffer(count),
                count_offset,
                max_draws,
                stride,
            )
        };
    }

    fn mesh_shader(&self) -> &ash::ext::mesh_shader::Device {
        self.ctx.mesh_shader.as_ref().unwrap_or_else(|| {
            panic!(
                "pass '{}': the device has no mesh shaders (check Capabilities::mesh_shader)",
                self.pass.name
            )
        })
    }

    /// Launches `x * y * z` task (or mesh) workgroups of the bound mesh pipeline.
    pub fn draw_mesh_tasks(&self, x: u32, y: u32, z: u32) {
        let mesh = self.mesh_shader();
        // SAFETY: recording inside the rendering scope; VK_EXT_mesh_shader is enabled.
        unsafe { mesh.cmd_draw_mesh_tasks(self.cmd, x, y, z) };
    }

    /// `draw_count` mesh-task launches whose `vk::DrawMeshTasksIndirectCommandEXT`s lie in
    /// `args` (declared `IndirectRead`).
    pub fn draw_mesh_tasks_indirect(
        &self,
        args: BufferId,
        offset: u64,
        draw_count: u32,
        stride: u32,
    ) {
        let mesh = self.mesh_shader();
        self.check_indirect(
            "draw_mesh_tasks_indirect",
            args,
            offset,
            draw_count,
            stride,
            12,
        );
        // SAFETY: recording inside the rendering scope; arguments declared IndirectRead.
        unsafe {
            mesh.cmd_draw_mesh_tasks_indirect(
                self.cmd,
                self.buffer(args),
                offset,
                draw_count,
                stride,
            )
        };
    }

    /// A 1D dispatch of `groups` workgroups, folded into rows past `bind::MAX_GROUPS`
    /// (`bind::fold_groups`).
    pub fn dispatch_groups(&self, groups: u64) {
        let (x, y) = fold_groups(groups);
        self.dispatch(x, y, 1);
    }

    pub fn dispatch(&self, x: u32, y: u32, z: u32) {
        // SAFETY: recording outside rendering with a bound compute pipeline.
        unsafe { self.ctx.device.cmd_dispatch(self.cmd, x, y, z) };
    }

    /// A dispatch whose group counts (`vk::DispatchIndirectCommand`) are read from `args` at
    /// `offset` (declared `IndirectRead`).
    pub fn dispatch_indirect(&self, args: BufferId, offset: u64) {
        self.check_indirect("dispatch_indirect", args, offset, 1, 12, 12);
        // SAFETY: recording outside rendering with a bound compute pipeline; arguments
        // declared IndirectRead.
        unsafe {
            self.ctx
                .device
                .cmd_dispatch_indirect(self.cmd, self.buffer(args), offset)
        };
    }

    fn check_transfer(&self, what: &str, id: ImageId, mip: u32, dst: bool) {
        let needs = if dst {
            Access::TransferDst
        } else {
            Access::TransferSrc
        };
        self.check_mips(what, id, mip, 1, format_args!("{needs:?}"), |a| a == needs);
    }

    /// The size of mip `mip` of `id` as a copy extent.
    fn mip_extent(&self, id: ImageId, mip: u32) -> vk::Extent3D {
        let (width, height) = self.desc(id).level_extent(mip);
        vk::Extent3D {
            width,
            height,
            depth: 1,
        }
    }

    /// Scales mip `src_mip` of `src` onto mip `dst_mip` of `dst` (declared TransferSrc /
    /// TransferDst on those levels). Also presents to swapchain images (mip 0 to mip 0).
    pub fn blit(&self, src: ImageId, src_mip: u32, dst: ImageId, dst_mip: u32) {
        self.check_transfer("blit", src, src_mip, false);
        self.check_transfer("blit", dst, dst_mip, true);
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
            .src_subresource(layers(vk::ImageAspectFlags::COLOR, src_mip))
            .src_offsets(corner(self.desc(src), src_mip))
            .dst_subresource(layers(vk::ImageAspectFlags::COLOR, dst_mip))
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
        self.check_transfer("copy_mip", src, mip, false);
        self.check_transfer("copy_mip", dst, mip, true);
        let region = vk::ImageCopy::default()
            .src_subresource(layers(vk::ImageAspectFlags::COLOR, mip))
            .dst_subresource(layers(vk::ImageAspectFlags::COLOR, mip))
            .extent(self.mip_extent(src, mip));
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
        self.check_transfer("clear", image, mip, true);
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

    /// Copies mip `mip` of `image` (tightly packed) into `buffer` at offset 0 (declared
    /// TransferSrc on the level, TransferDst on the buffer).
    pub fn copy_image_to_buffer(&self, image: ImageId, mip: u32, buffer: BufferId) {
        self.check_transfer("copy_image_to_buffer", image, mip, false);
        self.check_buffer_is(
            "copy_image_to_buffer",
            buffer,
            BufferRange::new(0, 1),
            Access::TransferDst,
        );
        let region = vk::BufferImageCopy::default()
            .image_subresource(layers(self.desc(image).aspect(), mip))
            .image_extent(self.mip_extent(image, mip));
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

    /// Fills `range` of `buffer` (declared TransferDst) with the 32-bit `value`.
    pub fn fill_buffer(&self, buffer: BufferId, range: BufferRange, value: u32) {
        self.check_buffer_is("fill_buffer", buffer, range, Access::TransferDst);
        // SAFETY: recording outside rendering; the range was declared TransferDst.
        unsafe {
            self.ctx.device.cmd_fill_buffer(
                self.cmd,
                self.buffer(buffer),
                range.offset,
                range.size,
                value,
            )
        };
    }

    /// Copies `regions` from `src` (declared TransferSrc) to `dst` (declared TransferDst).
    pub fn copy_buffer(&self, src: BufferId, dst: BufferId, regions: &[vk::BufferCopy]) {
        for r in regions {
            self.check_buffer_is(
                "copy_buffer",
                src,
                BufferRange::new(r.src_offset, r.size),
                Access::TransferSrc,
            );
            self.check_buffer_is(
                "copy_buffer",
                dst,
                BufferRange::new(r.dst_offset, r.size),
                Access::TransferDst,
            );
        }
        // SAFETY: recording outside rendering; both sides declared (checked above).
        unsafe {
            self.ctx
                .device
                .cmd_copy_buffer(self.cmd, self.buffer(src), self.buffer(dst), regions)
        };
    }

    /// Writes `bytes` (a multiple of 4, at most 65536) into `buffer` at `offset` (declared
    /// TransferDst).
    pub fn update_buffer(&self, buffer: BufferId, offset: u64, bytes: &[u8]) {
        self.check_buffer_is(
            "update_buffer",
            buffer,
            BufferRange::new(offset, bytes.len() as u64),
            Access::TransferDst,
        );
        // SAFETY: recording outside rendering; the bytes were declared TransferDst.
        unsafe {
            self.ctx
                .device
                .cmd_update_buffer(self.cmd, self.buffer(buffer), offset, bytes)
        };
    }
}

fn layers(aspect_mask: vk::ImageAspectFlags, mip: u32) -> vk::ImageSubresourceLayers {
    vk::ImageSubresourceLayers {
        aspect_mask,
        mip_level: mip,
        base_array_layer: 0,
        layer_count: 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buffer_use(id: u32, offset: u64, size: u64, access: Access) -> (Subresource, Access) {
        (
            Subresource::Buffer(BufferId(id), BufferRange::new(offset, size)),
            access,
        )
    }

    #[test]
    fn declared_buffer_ranges_must_cover_the_bytes_a_command_uses() {
        let uses = [
            buffer_use(0, 0, 16, Access::IndirectRead),
            buffer_use(0, 16, 16, Access::IndirectRead),
            buffer_use(1, 0, vk::WHOLE_SIZE, Access::TransferDst),
        ];
        let indirect = |a| a == Access::IndirectRead;
        let covered = |id, offset, size| {
            buffer_declared(
                &uses,
                BufferId(id),
                64,
                BufferRange::new(offset, size),
                indirect,
            )
        };
        assert!(covered(0, 4, 12), "inside the first range");
        assert!(covered(0, 8, 20), "spans both adjacent ranges");
        assert!(!covered(0, 24, 12), "reaches past the declared bytes");
        assert!(!covered(1, 0, 4), "declared, but with another access");
        assert!(buffer_declared(
            &uses,
            BufferId(1),
            64,
            BufferRange::WHOLE,
            |a| a == Access::TransferDst
        ));
    }

    #[test]
    fn declared_mips_must_cover_every_bound_level() {
        let uses = [(
            Subresource::Image {
                id: ImageId(0),
                base: 1,
                count: 2,
            },
            Access::Sampled(super::super::Stages::Fragment),
        )];
        let sampled = |a| matches!(a, Access::Sampled(_));
        assert!(mips_declared(&uses, ImageId(0), 1, 2, sampled));
        assert!(!mips_declared(&uses, ImageId(0), 0, 2, sampled));
        assert!(!mips_declared(&uses, ImageId(0), 2, 1, is_storage));
    }
}

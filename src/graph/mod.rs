//! The render graph. Passes declare the resources they read and write; the graph keeps their
//! declaration order (which is a valid topological order: a pass can only use resources
//! declared or written before it), derives every barrier and layout transition with
//! synchronization2, owns transient images and buffers, wraps each pass in a timestamp scope
//! and a debug label, and prints its schedule.
//!
//! A pass is one expression: its shader(s) and bindings, declared once (`bind::Bind`), give
//! the pipeline (created when the graph compiles, one per distinct program), the pass's
//! accesses and the descriptors it pushes (`pass.rs`).
//! ```ignore
//! let binds = [
//!     Bind::buffer(BINDING_FRAME, frame, Access::UniformRead(Stages::Graphics)),
//!     Bind::buffer(BINDING_POINTS, points, Access::StorageRead(Stages::Vertex)),
//! ];
//! g.draw("project", desc, &binds)
//!     .declare(|p| p.buffer_range(args, BufferRange::new(0, 16), Access::IndirectRead))
//!     .color(color, Load::Clear([0.0; 4]))
//!     .depth(depth, Load::Clear([0.0; 4]))
//!     .draw(move |ctx| ctx.draw_indirect(args, 0, 1, 16));
//! g.compute("resolve", "family/resolve.comp", &resolve_binds)
//!     .push(&params)
//!     .dispatch_grid(groups);
//! ```
//! Transfers and transitions use `pass(name)` with explicit accesses and a `record` closure.
//!
//! Stages: `validate.rs` (declarations) and culling, `derive.rs` (barriers per pass for the
//! first and the steady-state frame, on top of the pure state machine in `sync.rs`),
//! `compile.rs` (allocation with derived usage flags, views, samplers) and `record.rs`
//! (recording; `PassContext` checks every command against the pass's declarations).

pub mod bind;
mod compile;
mod derive;
pub mod pass;
mod record;
pub mod sync;
mod validate;

use std::fmt;
use std::sync::Arc;

use ash::vk;

use crate::gpu::{Buffer, Image, ImageDesc};

pub use bind::Bind;
pub use compile::CompiledGraph;
pub use derive::{Barrier, BarrierTarget};
pub use pass::{Binds, ComputePass, DrawPass};
pub use record::{Descriptor, PassContext, Sampler};
pub use sync::{Access, StageSupport, Stages};

/// Most color attachments of one pass (recording keeps them in a fixed-size array).
pub const MAX_COLOR_ATTACHMENTS: usize = 8;

/// Most descriptors of one `PassContext::bind` (pushed from a fixed-size array).
pub const MAX_DESCRIPTORS: usize = 16;

/// Handle to an image of the graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageId(pub(crate) u32);

/// Handle to a buffer of the graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BufferId(pub(crate) u32);

/// Two images used alternately level by level (pyramid ping-pong): level `l` lives in `a` for
/// even `l` and in `b` for odd `l`, so a pass reading level `l - 1` never writes the image it
/// samples. `copy` passes fill each image's missing levels when a later pass needs all levels
/// of one image (000 §4.2.4, Fig. 4.13).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PingPong {
    pub a: ImageId,
    pub b: ImageId,
}

impl PingPong {
    /// The image holding level `level`.
    pub fn holder(&self, level: u32) -> ImageId {
        if level.is_multiple_of(2) {
            self.a
        } else {
            self.b
        }
    }

    /// The image not holding level `level`.
    pub fn other(&self, level: u32) -> ImageId {
        if level.is_multiple_of(2) {
            self.b
        } else {
            self.a
        }
    }
}

/// Where a resource's memory comes from and how its state carries between frames.
pub enum ImageSource {
    /// Allocated by the graph at compile time; contents do not survive the frame.
    Transient(ImageDesc),
    /// Allocated by the graph; contents and layout survive into the next frame.
    History(ImageDesc),
    /// Owned elsewhere (input textures).
    Imported(Arc<Image>),
    /// Set every frame before execution (swapchain images).
    External(ImageDesc),
}

/// Where a buffer comes from.
pub enum BufferSource {
    Transient {
        size: u64,
        usage: vk::BufferUsageFlags,
    },
    Imported(Arc<Buffer>),
    /// Owned elsewhere and bound per frame with `CompiledGraph::bind_external_buffer` (one
    /// buffer per frame in flight, e.g. the frame uniforms). The graph tracks it as one
    /// resource: every bound buffer must be used the same way each frame.
    External {
        size: u64,
        usage: vk::BufferUsageFlags,
    },
}

pub(crate) struct ImageRes {
    pub name: String,
    pub source: ImageSource,
    /// The access an imported image was last used with before the graph's first frame.
    pub initial: Option<Access>,
}

impl ImageRes {
    pub fn desc(&self) -> ImageDesc {
        match &self.source {
            ImageSource::Transient(d) | ImageSource::History(d) | ImageSource::External(d) => *d,
            ImageSource::Imported(i) => i.desc,
        }
    }
}

pub(crate) struct BufferRes {
    pub name: String,
    pub source: BufferSource,
    /// The access an imported buffer was last used with before the graph's first frame.
    pub initial: Option<Access>,
}

impl BufferRes {
    pub fn size(&self) -> u64 {
        match &self.source {
            BufferSource::Transient { size, .. } | BufferSource::External { size, .. } => *size,
            BufferSource::Imported(b) => b.size,
        }
    }
}

/// Bytes `offset..offset + size` of a buffer; `size == vk::WHOLE_SIZE` reaches its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BufferRange {
    pub offset: u64,
    pub size: u64,
}

impl BufferRange {
    /// The whole buffer.
    pub const WHOLE: BufferRange = BufferRange {
        offset: 0,
        size: vk::WHOLE_SIZE,
    };

    pub fn new(offset: u64, size: u64) -> Self {
        Self { offset, size }
    }

    /// `start..end`, where `end == u64::MAX` means the end of the buffer.
    pub(crate) fn span(start: u64, end: u64) -> Self {
        Self {
            offset: start,
            size: if end == u64::MAX {
                vk::WHOLE_SIZE
            } else {
                end - start
            },
        }
    }

    /// One past the last byte (`u64::MAX`: the end of the buffer).
    pub fn end(self) -> u64 {
        if self.size == vk::WHOLE_SIZE {
            u64::MAX
        } else {
            self.offset.saturating_add(self.size)
        }
    }
}

impl fmt::Display for BufferRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.size == vk::WHOLE_SIZE {
            write!(f, "{}..", self.offset)
        } else {
            write!(f, "{}..{}", self.offset, self.end())
        }
    }
}

/// Which part of a resource an access touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Subresource {
    /// Mip levels `base..base + count` of an image.
    Image { id: ImageId, base: u32, count: u32 },
    /// A range of a buffer.
    Buffer(BufferId, BufferRange),
}

/// How a color attachment starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Load {
    Clear([f32; 4]),
    Load,
    DontCare,
}

/// One color or depth attachment of a pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attachment {
    pub image: ImageId,
    pub mip: u32,
    pub load: Load,
}

type RecordFn = Box<dyn Fn(&PassContext<'_>)>;

/// A declared pass.
pub(crate) struct PassDecl {
    pub name: String,
    pub uses: Vec<(Subresource, Access)>,
    pub colors: Vec<Attachment>,
    pub depth: Option<Attachment>,
    pub on_demand: bool,
    /// The placeholder buffer of the pass's `Bind::unused` bindings.
    pub unused: Option<BufferId>,
    /// The pipeline the graph creates for the pass (`compute` and `draw` passes).
    pub program: Option<pass::Program>,
    pub record: RecordFn,
}

/// Declares resources and passes; `compile` turns it into an executable graph.
#[derive(Default)]
pub struct GraphBuilder {
    pub(crate) images: Vec<ImageRes>,
    pub(crate) buffers: Vec<BufferRes>,
    pub(crate) passes: Vec<PassDecl>,
}

impl GraphBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    fn add_image(&mut self, name: &str, source: ImageSource) -> ImageId {
        self.images.push(ImageRes {
            name: name.into(),
            source,
            initial: None,
        });
        ImageId(self.images.len() as u32 - 1)
    }

    /// A transient image allocated by the graph.
    pub fn image(&mut self, name: &str, desc: ImageDesc) -> ImageId {
        self.add_image(name, ImageSource::Transient(desc))
    }

    /// An image whose contents survive to the next frame (e.g. the previous frame's color).
    pub fn history_image(&mut self, name: &str, desc: ImageDesc) -> ImageId {
        self.add_image(name, ImageSource::History(desc))
    }

    /// An image owned outside the graph.
    pub fn import_image(&mut self, name: &str, image: Arc<Image>) -> ImageId {
        self.add_image(name, ImageSource::Imported(image))
    }

    /// An image owned outside the graph whose contents are valid and which was last used
    /// with `initial` (in that access's layout): the first frame's barriers start from there
    /// instead of UNDEFINED, so the contents are kept.
    pub fn import_image_with(&mut self, name: &str, image: Arc<Image>, initial: Access) -> ImageId {
        let id = self.import_image(name, image);
        self.images[id.0 as usize].initial = Some(initial);
        id
    }

    /// An image bound per frame with `CompiledGraph::bind_external` (swapchain images).
    pub fn external_image(&mut self, name: &str, desc: ImageDesc) -> ImageId {
        self.add_image(name, ImageSource::External(desc))
    }

    /// A ping-pong pair of transient images with `desc`'s mip chain.
    pub fn ping_pong(&mut self, name: &str, desc: ImageDesc) -> PingPong {
        PingPong {
            a: self.image(&format!("{name}.a"), desc),
            b: self.image(&format!("{name}.b"), desc),
        }
    }

    fn add_buffer(
        &mut self,
        name: &str,
        source: BufferSource,
        initial: Option<Access>,
    ) -> BufferId {
        self.buffers.push(BufferRes {
            name: name.into(),
            source,
            initial,
        });
        BufferId(self.buffers.len() as u32 - 1)
    }

    /// A transient buffer. `usage` is extended by the usages its declared accesses need.
    pub fn buffer(&mut self, name: &str, size: u64, usage: vk::BufferUsageFlags) -> BufferId {
        self.add_buffer(name, BufferSource::Transient { size, usage }, None)
    }

    /// A buffer owned outside the graph (point data, per-frame uniforms, readback targets).
    pub fn import_buffer(&mut self, name: &str, buffer: Arc<Buffer>) -> BufferId {
        self.add_buffer(name, BufferSource::Imported(buffer), None)
    }

    /// A buffer of `size` bytes with `usage` bound per frame with
    /// `CompiledGraph::bind_external_buffer` (per-frame-slot uniforms). Accesses are checked
    /// against `usage`, and every bound buffer must have it and at least `size` bytes.
    pub fn external_buffer(
        &mut self,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> BufferId {
        self.add_buffer(name, BufferSource::External { size, usage }, None)
    }

    /// An imported buffer last used with `initial` before the graph's first frame (e.g.
    /// `TransferDst` after an upload): the first frame waits on that use.
    pub fn import_buffer_with(
        &mut self,
        name: &str,
        buffer: Arc<Buffer>,
        initial: Access,
    ) -> BufferId {
        self.add_buffer(name, BufferSource::Imported(buffer), Some(initial))
    }

    /// A pass that fills `range` of `buffer` with the 32-bit `value` (`vkCmdFillBuffer`;
    /// offset and size multiples of 4, or a size of `vk::WHOLE_SIZE`).
    pub fn fill_buffer(&mut self, name: &str, buffer: BufferId, range: BufferRange, value: u32) {
        self.pass(name)
            .buffer_range(buffer, range, Access::TransferDst)
            .record(move |ctx| ctx.fill_buffer(buffer, range, value));
    }

    /// A pass that copies `regions` from `src` to `dst` (`vkCmdCopyBuffer`).
    pub fn copy_buffer(
        &mut self,
        name: &str,
        src: BufferId,
        dst: BufferId,
        regions: &[vk::BufferCopy],
    ) {
        let mut pass = self.pass(name);
        for r in regions {
            pass = pass
                .buffer_range(
                    src,
                    BufferRange::new(r.src_offset, r.size),
                    Access::TransferSrc,
                )
                .buffer_range(
                    dst,
                    BufferRange::new(r.dst_offset, r.size),
                    Access::TransferDst,
                );
        }
        let regions = regions.to_vec();
        pass.record(move |ctx| ctx.copy_buffer(src, dst, &regions));
    }

    /// A pass that writes `bytes` (at most 65536, a multiple of 4) into `buffer` at `offset`
    /// from the command buffer (`vkCmdUpdateBuffer`).
    pub fn update_buffer(&mut self, name: &str, buffer: BufferId, offset: u64, bytes: &[u8]) {
        let range = BufferRange::new(offset, bytes.len() as u64);
        let bytes = bytes.to_vec();
        self.pass(name)
            .buffer_range(buffer, range, Access::TransferDst)
            .record(move |ctx| ctx.update_buffer(buffer, offset, &bytes));
    }

    /// Description of a declared image.
    pub fn desc(&self, id: ImageId) -> ImageDesc {
        self.images[id.0 as usize].desc()
    }

    /// Starts declaring a pass; finish it with `record`.
    pub fn pass(&mut self, name: &str) -> PassBuilder<'_> {
        PassBuilder {
            graph: self,
            decl: Some(PassDecl {
                name: name.into(),
                uses: Vec::new(),
                colors: Vec::new(),
                depth: None,
                on_demand: false,
                unused: None,
                program: None,
                record: Box::new(|_| {}),
            }),
        }
    }
}

/// Declares one pass's accesses.
pub struct PassBuilder<'g> {
    graph: &'g mut GraphBuilder,
    decl: Option<PassDecl>,
}

impl PassBuilder<'_> {
    fn decl(&mut self) -> &mut PassDecl {
        self.decl.as_mut().expect("pass already recorded")
    }

    /// A color attachment at `image`'s mip 0; attachment order is the MRT location order.
    pub fn color(self, image: ImageId, load: Load) -> Self {
        self.color_mip(image, 0, load)
    }

    /// A color attachment at one mip level.
    pub fn color_mip(mut self, image: ImageId, mip: u32, load: Load) -> Self {
        let d = self.decl();
        d.colors.push(Attachment { image, mip, load });
        d.uses.push((
            Subresource::Image {
                id: image,
                base: mip,
                count: 1,
            },
            Access::ColorAttachment,
        ));
        self
    }

    /// The depth attachment, cleared to `clear` (reversed-Z: 0 is the far plane).
    pub fn depth(mut self, image: ImageId, load: Load) -> Self {
        let d = self.decl();
        d.depth = Some(Attachment {
            image,
            mip: 0,
            load,
        });
        d.uses.push((
            Subresource::Image {
                id: image,
                base: 0,
                count: 1,
            },
            Access::DepthAttachment,
        ));
        self
    }

    /// Any access to all mip levels of an image.
    pub fn image(self, image: ImageId, access: Access) -> Self {
        let levels = self.graph.desc(image).mip_levels;
        self.image_mips(image, 0, levels, access)
    }

    /// Any access to mip levels `base..base + count` of an image.
    pub fn image_mips(mut self, id: ImageId, base: u32, count: u32, access: Access) -> Self {
        self.decl()
            .uses
            .push((Subresource::Image { id, base, count }, access));
        self
    }

    /// Any access to a whole buffer.
    pub fn buffer(self, id: BufferId, access: Access) -> Self {
        self.buffer_range(id, BufferRange::WHOLE, access)
    }

    /// Any access to a range of a buffer. Several accesses of one pass to one buffer (or
    /// overlapping ranges) are merged into one state.
    pub fn buffer_range(mut self, id: BufferId, range: BufferRange, access: Access) -> Self {
        self.decl()
            .uses
            .push((Subresource::Buffer(id, range), access));
        self
    }

    /// The accesses of `binds` (a placeholder buffer of the pass's own for the unused ones);
    /// `PassContext::bind_all` pushes their descriptors.
    pub fn binds(mut self, binds: &[bind::Bind]) -> Self {
        for b in binds {
            let sub = match b.resource {
                bind::Resource::Buffer(id, range) => Subresource::Buffer(id, range),
                bind::Resource::Uniform(id) => Subresource::Buffer(id, BufferRange::WHOLE),
                bind::Resource::StorageImage(id, mip) => Subresource::Image {
                    id,
                    base: mip,
                    count: 1,
                },
                bind::Resource::Sampled {
                    image, base, count, ..
                } => Subresource::Image {
                    id: image,
                    base,
                    count,
                },
                bind::Resource::Unused => {
                    let id = match self.decl().unused {
                        Some(id) => id,
                        None => {
                            let name = format!("{}.unused", self.decl().name);
                            let id = self.graph.buffer(
                                &name,
                                bind::UNUSED_BYTES,
                                vk::BufferUsageFlags::STORAGE_BUFFER,
                            );
                            self.decl().unused = Some(id);
                            id
                        }
                    };
                    Subresource::Buffer(id, BufferRange::WHOLE)
                }
            };
            self.decl().uses.push((sub, b.access));
        }
        self
    }

    /// Marks the pass as recorded only in frames that ask for it (readback). On-demand passes
    /// must come after every regular pass and are not timed.
    pub fn on_demand(mut self) -> Self {
        self.decl().on_demand = true;
        self
    }

    /// Sets the commands of the pass and adds it to the graph.
    pub fn record(mut self, f: impl Fn(&PassContext<'_>) + 'static) {
        let mut decl = self.decl.take().expect("pass recorded once");
        decl.record = Box::new(f);
        self.graph.passes.push(decl);
    }
}

//! The render graph. Passes declare the resources they read and write; the graph keeps their
//! declaration order (which is a valid topological order: a pass can only use resources
//! declared or written before it), derives every barrier and layout transition with
//! synchronization2, owns transient images and buffers, wraps each pass in a timestamp scope
//! and a debug label, and prints its schedule.
//!
//! A pass reads like a small function:
//! ```ignore
//! g.pass("project")
//!     .read(points, Access::StorageRead(Stages::Vertex))
//!     .color(color, Load::Clear([0.0; 4]))
//!     .depth(depth, 0.0)
//!     .record(move |ctx| ctx.draw(&pipeline, count));
//! ```

mod exec;
pub mod sync;

use std::sync::Arc;

use ash::vk;

use crate::gpu::{Buffer, Image, ImageDesc};

pub use exec::{Barrier, BarrierTarget, CompiledGraph, Descriptor, PassContext};
pub use sync::{Access, Stages};

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
}

pub(crate) struct ImageRes {
    pub name: String,
    pub source: ImageSource,
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
}

/// Which part of a resource an access touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Subresource {
    /// Mip levels `base..base + count` of an image.
    Image {
        id: ImageId,
        base: u32,
        count: u32,
    },
    Buffer(BufferId),
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

    /// A transient buffer.
    pub fn buffer(&mut self, name: &str, size: u64, usage: vk::BufferUsageFlags) -> BufferId {
        self.buffers.push(BufferRes {
            name: name.into(),
            source: BufferSource::Transient { size, usage },
        });
        BufferId(self.buffers.len() as u32 - 1)
    }

    /// A buffer owned outside the graph (point data, per-frame uniforms, readback targets).
    pub fn import_buffer(&mut self, name: &str, buffer: Arc<Buffer>) -> BufferId {
        self.buffers.push(BufferRes {
            name: name.into(),
            source: BufferSource::Imported(buffer),
        });
        BufferId(self.buffers.len() as u32 - 1)
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

    /// Any access to a buffer.
    pub fn buffer(mut self, id: BufferId, access: Access) -> Self {
        self.decl().uses.push((Subresource::Buffer(id), access));
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

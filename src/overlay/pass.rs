//! The overlay's graph pass: instanced quads alpha-blended over the frame's color target.
//!
//! The atlas is a device-local storage buffer uploaded once per renderer. The quads of each
//! frame slot live in a host-visible buffer of `CAPACITY` quads bound to the graph's external
//! `overlay.glyphs` buffer by `begin_frame`, like the frame uniforms; the host fills it after the
//! slot's fence, and the pass draws 6 vertices per quad for the quads written.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;

use anyhow::Result;
use ash::vk;
use gpu_allocator::MemoryLocation;

use super::{atlas, layout, Mark, Panel, CAPACITY};
use crate::gpu::{Blend, Buffer, Context, GraphicsDesc};
use crate::graph::{Access, Bind, BufferId, CompiledGraph, GraphBuilder, ImageId, Load, Stages};
use crate::layout::{GpuGlyph, BINDING_FRAME, BINDING_OVERLAY_ATLAS, BINDING_OVERLAY_GLYPHS};

/// The overlay of one renderer: per frame slot a quad buffer, and the quad count of the frame
/// being recorded.
pub struct OverlayPass {
    slots: Vec<Buffer>,
    glyphs: BufferId,
    /// Quads of the current frame, read by the pass's record function.
    count: Arc<AtomicU32>,
    /// Host copy of the current frame's quads (allocated once).
    staging: Vec<GpuGlyph>,
    width: u32,
    height: u32,
}

impl OverlayPass {
    /// Adds the `overlay.text` pass drawing over `color` (RGBA8, sRGB-encoded values) of a
    /// `width`-pixel-wide frame, with `slots` frame slots; `frame` is the frame uniforms
    /// (the viewport).
    pub fn add(
        ctx: &Arc<Context>,
        g: &mut GraphBuilder,
        color: ImageId,
        frame: BufferId,
        slots: usize,
        (width, height): (u32, u32),
    ) -> Result<Self> {
        let atlas = atlas()?;
        let atlas_buffer = Arc::new(Buffer::with_data(
            ctx,
            "overlay.atlas",
            &atlas.texels,
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?);
        let bytes = (CAPACITY * std::mem::size_of::<GpuGlyph>()) as u64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let buffers = (0..slots.max(1))
            .map(|_| {
                Buffer::new(
                    ctx,
                    "overlay.glyphs",
                    bytes,
                    usage,
                    MemoryLocation::CpuToGpu,
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let glyphs = g.external_buffer("overlay.glyphs", bytes, usage);
        let atlas_id = g.import_buffer("overlay.atlas", atlas_buffer);
        let binds = [
            Bind::buffer(BINDING_FRAME, frame, Access::UniformRead(Stages::Vertex)),
            Bind::buffer(
                BINDING_OVERLAY_GLYPHS,
                glyphs,
                Access::StorageRead(Stages::Graphics),
            ),
            Bind::buffer(
                BINDING_OVERLAY_ATLAS,
                atlas_id,
                Access::StorageRead(Stages::Fragment),
            ),
        ];
        let desc = GraphicsDesc {
            shaders: vec!["overlay/text.vert", "overlay/text.frag"],
            color_formats: vec![g.desc(color).format],
            blends: vec![Blend::Alpha],
            ..GraphicsDesc::default()
        };
        let count = Arc::new(AtomicU32::new(0));
        let quads = count.clone();
        g.draw("overlay.text", desc, &binds)
            .color(color, Load::Load)
            .draw(move |ctx| ctx.draw(6, quads.load(Ordering::Relaxed)));
        Ok(Self {
            slots: buffers,
            glyphs,
            count,
            staging: vec![GpuGlyph::default(); CAPACITY],
            width,
            height,
        })
    }

    /// Binds slot `slot`'s quad buffer (after the slot's fence).
    pub fn bind(&self, graph: &mut CompiledGraph, slot: usize) {
        graph.bind_external_buffer(self.glyphs, &self.slots[slot]);
    }

    /// Lays out `panels` into slot `slot`'s quad buffer (the GPU is done with it) and sets the
    /// quad count the next recording draws. Returns the quads written.
    pub fn write(&mut self, slot: usize, panels: &[Panel], marks: &[Mark]) -> Result<usize> {
        let n = layout(
            atlas()?,
            panels,
            marks,
            (self.width, self.height),
            &mut self.staging,
        );
        self.slots[slot].write(bytemuck::cast_slice(&self.staging[..n]))?;
        self.count.store(n as u32, Ordering::Relaxed);
        Ok(n)
    }
}

//! `mesh`: the ground truth. Renders the input triangles at `samples` x `samples` the output
//! resolution (linear color, linear depth, normal) and resolves them in a compute pass.

use anyhow::{bail, Result};
use ash::vk;

use crate::gpu::{Blend, GraphicsDesc, ImageDesc};
use crate::graph::{Access, Bind, Binds, BufferId, BufferRange, Load, Stages};
use crate::layout::{BINDING_INPUT0, BINDING_INPUT1, BINDING_INPUT2, RESOLVE_GROUP};
use crate::methods::{
    BuildContext, MethodInfo, ParamSpec, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT,
};

pub const INFO: MethodInfo = MethodInfo {
    params: &[ParamSpec {
        name: "samples",
        default: 4.0,
        min: 1.0,
        max: 8.0,
        doc: "supersampling factor per axis",
    }],
    needs_faces: true,
    ..MethodInfo::new(
        "mesh",
        "ground truth: the input triangle mesh, supersampled s x s and resolved",
        build,
    )
};

/// Linear HDR color of the supersampled pass.
const HI_COLOR_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    let Some(indices) = b.indices else {
        bail!("method 'mesh' needs triangle faces; this input has none");
    };
    let samples = b.config.get("samples").round().max(1.0) as u32;
    let count = b.scene.index_count;
    add_mesh(b, "mesh", samples, Indices::Static { indices, count })
}

/// Where the triangles' indices (into the point streams) come from.
#[derive(Clone, Copy, Debug)]
pub enum Indices {
    /// `count` indices of a buffer.
    Static { indices: BufferId, count: u32 },
    /// A `VkDrawIndexedIndirectCommand` at `range` of `args`, written by an earlier pass.
    Indirect {
        indices: BufferId,
        args: BufferId,
        range: BufferRange,
    },
}

/// Draws `indices`' triangles (vertices, normals and albedo from the point streams) at
/// `samples` x `samples` the output resolution and resolves them into the standard targets:
/// passes `{prefix}.raster` and `{prefix}.resolve`.
pub fn add_mesh(
    b: &mut BuildContext<'_>,
    prefix: &str,
    samples: u32,
    source: Indices,
) -> Result<()> {
    let (w, h) = (b.width * samples, b.height * samples);
    if w > b.ctx.caps.max_image_dimension_2d || h > b.ctx.caps.max_image_dimension_2d {
        bail!("{w}x{h} supersampled target exceeds the device limit");
    }
    let target = |format, usage| ImageDesc {
        format,
        width: w,
        height: h,
        mip_levels: 1,
        usage,
    };
    let color_usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::STORAGE;
    let hi_color = b.graph.image(
        &format!("{prefix}.hi_color"),
        target(HI_COLOR_FORMAT, color_usage),
    );
    let hi_depth = b.graph.image(
        &format!("{prefix}.hi_depth"),
        target(DEPTH_FORMAT, color_usage),
    );
    let hi_normal = b.graph.image(
        &format!("{prefix}.hi_normal"),
        target(NORMAL_FORMAT, color_usage),
    );
    let zbuffer = b.graph.image(
        &format!("{prefix}.zbuffer"),
        target(
            ZBUFFER_FORMAT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        ),
    );
    let t = b.targets;
    let desc = GraphicsDesc {
        shaders: vec!["mesh/mesh.vert", "mesh/mesh.frag"],
        color_formats: vec![HI_COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT],
        blends: vec![Blend::Replace; 3],
        depth_format: Some(ZBUFFER_FORMAT),
        depth_test: true,
        depth_write: true,
        depth_compare: vk::CompareOp::GREATER,
        ..Default::default()
    };
    b.graph
        .draw(&format!("{prefix}.raster"), desc, &b.draw_binds())
        .declare(|pass| match source {
            Indices::Static { indices, .. } => pass.buffer(indices, Access::IndexRead),
            Indices::Indirect {
                indices,
                args,
                range,
            } => pass.buffer(indices, Access::IndexRead).buffer_range(
                args,
                range,
                Access::IndirectRead,
            ),
        })
        .color(hi_color, Load::Clear([0.0; 4]))
        .color(hi_depth, Load::Clear([0.0; 4]))
        .color(hi_normal, Load::Clear([0.0; 4]))
        .depth(zbuffer, Load::Clear([0.0; 4]))
        .draw(move |ctx| match source {
            Indices::Static { indices, count } => ctx.draw_indexed(indices, count),
            Indices::Indirect {
                indices,
                args,
                range,
            } => ctx.draw_indexed_indirect(indices, args, range.offset, 1, 20),
        });
    let read = Access::StorageRead(Stages::Compute);
    let mut binds = Binds::from([
        Bind::image(BINDING_INPUT0, hi_color, 0, read),
        Bind::image(BINDING_INPUT1, hi_depth, 0, read),
        Bind::image(BINDING_INPUT2, hi_normal, 0, read),
    ]);
    for bind in t.compute_writes() {
        binds.push(bind);
    }
    let groups = b.pixel_groups(RESOLVE_GROUP);
    b.graph
        .compute(&format!("{prefix}.resolve"), "mesh/resolve.comp", &binds)
        .push(&samples)
        .dispatch_grid(groups);
    Ok(())
}

//! `points`: fixed-size points (002 §5.2, method 1), 1 px or N px, nearest depth wins.

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use crate::gpu::layout::{BINDING_FRAME, BINDING_SEGMENTS};
use crate::gpu::{Binding, Blend, GraphicsDesc, ImageDesc, Pipeline};
use crate::graph::Descriptor;
use crate::graph::{Access, Load, Stages};
use crate::methods::{
    BuildContext, MethodInfo, ParamSpec, COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT,
};

pub const INFO: MethodInfo = MethodInfo {
    name: "points",
    summary: "fixed-size points, one vertex per point, nearest depth wins (002 §5.2 method 1)",
    params: &[ParamSpec {
        name: "size",
        default: 1.0,
        min: 1.0,
        max: 64.0,
        doc: "point size in pixels",
    }],
    needs_faces: false,
    features: &[],
    culls_batches: false,
    needs_lod: false,
    needs_hpr: false,
    needs_normal_field: false,
    needs_surfels: false,
    build,
};

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    let stages = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
    let pipeline = Arc::new(Pipeline::graphics(
        b.ctx,
        &GraphicsDesc {
            shaders: &["splat/points.vert", "splat/points.frag"],
            bindings: &[
                Binding::new(BINDING_FRAME, vk::DescriptorType::STORAGE_BUFFER, stages),
                Binding::new(
                    BINDING_SEGMENTS,
                    vk::DescriptorType::STORAGE_BUFFER,
                    vk::ShaderStageFlags::VERTEX,
                ),
            ],
            color_formats: &[COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT],
            blends: &[Blend::Replace; 3],
            depth_format: Some(ZBUFFER_FORMAT),
            depth_test: true,
            depth_write: true,
            depth_compare: vk::CompareOp::GREATER,
            topology: vk::PrimitiveTopology::POINT_LIST,
            cull: vk::CullModeFlags::NONE,
            specialization: &[],
            geometry_output: None,
        },
    )?);
    let zbuffer = b.graph.image(
        "points.zbuffer",
        ImageDesc {
            format: ZBUFFER_FORMAT,
            width: b.width,
            height: b.height,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        },
    );
    let (frame, segments, t) = (b.frame, b.segments, b.targets);
    let count = b.scene.point_count;
    b.graph
        .pass("points.project")
        .buffer(frame, Access::UniformRead(Stages::Graphics))
        .buffer(segments, Access::StorageRead(Stages::Vertex))
        .color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(zbuffer, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(
                &pipeline,
                &[
                    Descriptor::Buffer(BINDING_FRAME, frame),
                    Descriptor::Buffer(BINDING_SEGMENTS, segments),
                ],
            );
            ctx.draw(count, 1);
        });
    Ok(())
}

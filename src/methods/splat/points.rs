//! `points`: fixed-size points (002 §5.2, method 1), 1 px or N px, nearest depth wins.

use anyhow::Result;
use ash::vk;

use crate::gpu::{Blend, GraphicsDesc, ImageDesc};
use crate::graph::Load;
use crate::methods::{
    BuildContext, MethodInfo, ParamSpec, COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT,
};

pub const INFO: MethodInfo = MethodInfo {
    params: &[ParamSpec {
        name: "size",
        default: 1.0,
        min: 1.0,
        max: 64.0,
        doc: "point size in pixels",
    }],
    ..MethodInfo::new(
        "points",
        "fixed-size points, one vertex per point, nearest depth wins (002 §5.2 method 1)",
        build,
    )
};

fn build(b: &mut BuildContext<'_>) -> Result<()> {
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
    let desc = GraphicsDesc {
        shaders: vec!["splat/points.vert", "splat/points.frag"],
        color_formats: vec![COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT],
        blends: vec![Blend::Replace; 3],
        depth_format: Some(ZBUFFER_FORMAT),
        depth_test: true,
        depth_write: true,
        depth_compare: vk::CompareOp::GREATER,
        topology: vk::PrimitiveTopology::POINT_LIST,
        ..Default::default()
    };
    let (t, count) = (b.targets, b.scene.draw_points.clone());
    let binds = b.draw_binds();
    b.graph
        .draw("points.project", desc, &binds)
        .color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(zbuffer, Load::Clear([0.0; 4]))
        .draw(move |ctx| ctx.draw(count.get(), 1));
    Ok(())
}

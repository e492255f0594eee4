//! `points`: fixed-size points (002 §5.2, method 1), 1 px or N px, nearest depth wins.

use anyhow::Result;

use crate::graph::Load;
use crate::methods::{points_desc, BuildContext, MethodInfo, ParamSpec};

/// The point size in pixels.
pub(super) const SIZE: ParamSpec = ParamSpec {
    name: "size",
    default: 1.0,
    min: 1.0,
    max: 64.0,
    doc: "point size in pixels",
};

pub const INFO: MethodInfo = MethodInfo {
    params: &[SIZE],
    ..MethodInfo::new(
        "points",
        "fixed-size points, one vertex per point, nearest depth wins (002 §5.2 method 1)",
        build,
    )
};

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    add_points(b, "points", "splat/points.frag");
    Ok(())
}

/// Declares `{name}.project`: one vertex per point of `b`'s streams, `gl_PointSize` from the
/// `size` parameter, shaded by `fragment` into the standard targets, nearest depth wins.
pub(super) fn add_points(b: &mut BuildContext<'_>, name: &str, fragment: &'static str) {
    let zbuffer = b.zbuffer(&format!("{name}.zbuffer"));
    let desc = points_desc(&["splat/points.vert", fragment]);
    let (t, count) = (b.targets, b.scene.draw_points.clone());
    let binds = b.draw_binds();
    b.graph
        .draw(&format!("{name}.project"), desc, &binds)
        .color(t.color, Load::Clear([0.0; 4]))
        .color(t.depth, Load::Clear([0.0; 4]))
        .color(t.normal, Load::Clear([0.0; 4]))
        .depth(zbuffer, Load::Clear([0.0; 4]))
        .draw(move |ctx| ctx.draw(count.get(), 1));
}

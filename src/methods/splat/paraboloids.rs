//! `paraboloids`: fixed-size points drawn as screen-aligned paraboloids, Potree's
//! "paraboloid" point shape (Schütz 2016): each round point's depth rises towards its
//! centre by up to its radius, so where points overlap the nearer paraboloid wins per pixel
//! and neighbours at one depth meet along their bisector, as a Voronoi diagram, instead of
//! the square edges of `points`. Writing the fragment depth costs early depth testing.

use anyhow::Result;

use super::points::{add_points, SIZE};
use crate::methods::{BuildContext, MethodInfo, ParamSpec};

pub const INFO: MethodInfo = MethodInfo {
    params: &[ParamSpec {
        default: 4.0,
        ..SIZE
    }],
    ..MethodInfo::new(
        "paraboloids",
        "fixed-size round points as screen-aligned paraboloids (Potree): overlaps resolved \
         per pixel by depth",
        build,
    )
};

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    add_points(b, "paraboloids", "splat/paraboloid.frag");
    Ok(())
}

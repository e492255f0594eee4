//! The splatting family (002 sections 5.2-5.3): four rasterizations of a point as a hardware
//! point sprite (fixed-size points, image-aligned squares, affinely projected sprites,
//! perspective-correct splats), each with four shadings: flat (one pass, lit per splat) and the
//! three blended ones, which share a depth-only visibility pass, an additive accumulation of
//! weighted color and normal within a relative depth `epsilon` of the visible surface and a
//! normalization pass: Gouraud (lit per splat), Phong (a linear normal field per splat, fitted to
//! the neighbours' normals in preprocessing, `crate::scene::normal_field`, lit per fragment) and
//! deferred (albedo and normal blended, lit once per pixel in the normalization).
//! Every combination is one pair of shaders specialized by constants; the method name
//! `{raster}-{shading}` picks them.

pub mod paraboloids;
pub mod points;

use anyhow::{anyhow, Result};
use ash::vk;

use super::{
    BuildContext, MethodInfo, ParamSpec, COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT,
};
use crate::gpu::{Blend, GraphicsDesc, ImageDesc};
use crate::graph::{Access, Bind, ImageId, Load, Stages};
use crate::layout::{
    SplatParams, BINDING_FRAME, BINDING_INPUT0, BINDING_INPUT1, BINDING_INPUT2, BINDING_OUTPUT0,
    RESOLVE_GROUP, SPLAT_RASTER_AFFINE, SPLAT_RASTER_PERSPECTIVE, SPLAT_RASTER_POINTS,
    SPLAT_RASTER_SQUARES, SPLAT_SHADING_DEFERRED, SPLAT_SHADING_FLAT, SPLAT_SHADING_GOURAUD,
    SPLAT_SHADING_PHONG, SPLAT_SPEC_CULL, SPLAT_SPEC_RASTER, SPLAT_SPEC_SHADING,
};

/// The accumulation targets: (sum w c, sum w) and (sum w n, sum w), 16-bit float (002 5.3.2).
const ACCUM_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

const SIZE: ParamSpec = ParamSpec {
    name: "size",
    default: 1.0,
    min: 1.0,
    max: 64.0,
    doc: "point size in pixels",
};
const RADIUS: ParamSpec = ParamSpec {
    name: "radius",
    default: 1.0,
    min: 0.05,
    max: 20.0,
    doc: "scale of every point's radius",
};
const CULL: ParamSpec = ParamSpec {
    name: "cull",
    default: 0.0,
    min: 0.0,
    max: 1.0,
    doc: "1: cull splats whose normal faces away (needs consistently oriented normals)",
};
const EPSILON: ParamSpec = ParamSpec {
    name: "epsilon",
    default: 0.01,
    min: 0.0,
    max: 0.5,
    doc: "blending depth offset, relative to the depth",
};

const POINTS_FLAT: &[ParamSpec] = &[SIZE, CULL];
const SPLATS_FLAT: &[ParamSpec] = &[RADIUS, CULL];
const POINTS_BLENDED: &[ParamSpec] = &[SIZE, CULL, EPSILON];
const SPLATS_BLENDED: &[ParamSpec] = &[RADIUS, CULL, EPSILON];

const fn info(
    name: &'static str,
    summary: &'static str,
    params: &'static [ParamSpec],
) -> MethodInfo {
    MethodInfo {
        params,
        needs_surfels: true,
        ..MethodInfo::new(name, summary, build)
    }
}

/// `info` for a Phong variant: it reads the splats' linear normal fields.
const fn phong(
    name: &'static str,
    summary: &'static str,
    params: &'static [ParamSpec],
) -> MethodInfo {
    MethodInfo {
        needs_normal_field: true,
        needs_surfels: true,
        ..info(name, summary, params)
    }
}

pub const POINTS_FLAT_INFO: MethodInfo = info(
    "points-flat",
    "fixed-size point sprites, flat shading per splat (002 5.2.1, 5.3.1)",
    POINTS_FLAT,
);
pub const SQUARES_FLAT_INFO: MethodInfo = info(
    "squares-flat",
    "image-aligned squares of the projected radius (002 eq. 5.1), flat shading",
    SPLATS_FLAT,
);
pub const AFFINE_FLAT_INFO: MethodInfo = info(
    "affine-flat",
    "affinely projected oriented discs with corrected depth (002 eqs. 5.2-5.3), flat shading",
    SPLATS_FLAT,
);
pub const PERSPECTIVE_FLAT_INFO: MethodInfo = info(
    "perspective-flat",
    "perspective-correct splats: pixel rays meet the splat plane (002 eqs. 5.4-5.5), flat shading",
    SPLATS_FLAT,
);
pub const POINTS_DEFERRED_INFO: MethodInfo = info(
    "points-deferred",
    "fixed-size point sprites, deferred shading: albedo and normal blended, lit per pixel (002 5.3.4)",
    POINTS_BLENDED,
);
pub const SQUARES_DEFERRED_INFO: MethodInfo = info(
    "squares-deferred",
    "image-aligned squares (002 eq. 5.1), deferred shading (002 5.3.4)",
    SPLATS_BLENDED,
);
pub const AFFINE_DEFERRED_INFO: MethodInfo = info(
    "affine-deferred",
    "affinely projected discs (002 eqs. 5.2-5.3), deferred shading (002 5.3.4)",
    SPLATS_BLENDED,
);
pub const PERSPECTIVE_DEFERRED_INFO: MethodInfo = info(
    "perspective-deferred",
    "perspective-correct splats (002 eqs. 5.4-5.5), deferred shading (002 5.3.4)",
    SPLATS_BLENDED,
);

pub const POINTS_GOURAUD_INFO: MethodInfo = info(
    "points-gouraud",
    "fixed-size point sprites, Gouraud shading: per-splat colors blended (002 5.3.2)",
    POINTS_BLENDED,
);
pub const SQUARES_GOURAUD_INFO: MethodInfo = info(
    "squares-gouraud",
    "image-aligned squares (002 eq. 5.1), Gouraud shading (002 5.3.2)",
    SPLATS_BLENDED,
);
pub const AFFINE_GOURAUD_INFO: MethodInfo = info(
    "affine-gouraud",
    "affinely projected discs (002 eqs. 5.2-5.3), Gouraud shading (002 5.3.2)",
    SPLATS_BLENDED,
);
pub const PERSPECTIVE_GOURAUD_INFO: MethodInfo = info(
    "perspective-gouraud",
    "perspective-correct splats (002 eqs. 5.4-5.5), Gouraud shading (002 5.3.2)",
    SPLATS_BLENDED,
);
pub const POINTS_PHONG_INFO: MethodInfo = phong(
    "points-phong",
    "fixed-size point sprites, Phong shading: each splat's fitted linear normal field lit per fragment, blended (002 5.3.3)",
    POINTS_BLENDED,
);
pub const SQUARES_PHONG_INFO: MethodInfo = phong(
    "squares-phong",
    "image-aligned squares (002 eq. 5.1), Phong shading with fitted linear normal fields (002 5.3.3)",
    SPLATS_BLENDED,
);
pub const AFFINE_PHONG_INFO: MethodInfo = phong(
    "affine-phong",
    "affinely projected discs (002 eqs. 5.2-5.3), Phong shading with fitted linear normal fields (002 5.3.3)",
    SPLATS_BLENDED,
);
pub const PERSPECTIVE_PHONG_INFO: MethodInfo = phong(
    "perspective-phong",
    "perspective-correct splats (002 eqs. 5.4-5.5), Phong shading with fitted linear normal fields (002 5.3.3)",
    SPLATS_BLENDED,
);

/// The rasterization and shading a method name `{raster}-{shading}` stands for.
fn variant(name: &str) -> Result<(u32, u32)> {
    let (raster, shading) = name
        .split_once('-')
        .ok_or_else(|| anyhow!("'{name}' is not a splatting method"))?;
    let raster = match raster {
        "points" => SPLAT_RASTER_POINTS,
        "squares" => SPLAT_RASTER_SQUARES,
        "affine" => SPLAT_RASTER_AFFINE,
        "perspective" => SPLAT_RASTER_PERSPECTIVE,
        _ => return Err(anyhow!("'{name}': unknown splat rasterization")),
    };
    let shading = match shading {
        "flat" => SPLAT_SHADING_FLAT,
        "gouraud" => SPLAT_SHADING_GOURAUD,
        "phong" => SPLAT_SHADING_PHONG,
        "deferred" => SPLAT_SHADING_DEFERRED,
        _ => return Err(anyhow!("'{name}': unknown splat shading")),
    };
    Ok((raster, shading))
}

fn build(b: &mut BuildContext<'_>) -> Result<()> {
    let (raster, shading) = variant(b.config.method.name)?;
    let cull = u32::from(b.config.get("cull") >= 0.5);
    let specialization = [
        (SPLAT_SPEC_RASTER, raster),
        (SPLAT_SPEC_SHADING, shading),
        (SPLAT_SPEC_CULL, cull),
    ];
    let params = SplatParams {
        radius_scale: b.config.get("radius"),
        epsilon: b.config.get("epsilon"),
        max_point_size: b.ctx.caps.point_size_range[1],
        pad0: 0,
    };
    let zbuffer = b.zbuffer("splat.zbuffer");
    let splats = Splats {
        specialization,
        params,
        zbuffer,
    };
    if shading == SPLAT_SHADING_FLAT {
        splats.flat(b)
    } else {
        splats.blended(b)
    }
}

/// What every pass of one method shares.
struct Splats {
    specialization: [(u32, u32); 3],
    params: SplatParams,
    zbuffer: ImageId,
}

impl Splats {
    /// A point-sprite pipeline state with `fragment`, writing `formats` with `blend`.
    fn desc(
        &self,
        fragment: &'static str,
        formats: &[vk::Format],
        blend: Blend,
        visibility: bool,
    ) -> GraphicsDesc {
        GraphicsDesc {
            shaders: vec!["splat/splat.vert", fragment],
            color_formats: formats.to_vec(),
            blends: vec![blend; formats.len()],
            depth_format: Some(ZBUFFER_FORMAT),
            depth_test: true,
            // The blending pass tests against the visibility depth without writing it.
            depth_write: visibility,
            depth_compare: if visibility {
                vk::CompareOp::GREATER
            } else {
                vk::CompareOp::GREATER_OR_EQUAL
            },
            topology: vk::PrimitiveTopology::POINT_LIST,
            specialization: self.specialization.to_vec(),
            ..Default::default()
        }
    }

    /// Flat shading: one pass into the standard targets.
    fn flat(self, b: &mut BuildContext<'_>) -> Result<()> {
        let formats = [COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT];
        let desc = self.desc("splat/flat.frag", &formats, Blend::Replace, true);
        let (binds, t, count) = (b.draw_binds(), b.targets, b.scene.draw_points.clone());
        b.graph
            .draw("splat.flat", desc, &binds)
            .push(&self.params)
            .color(t.color, Load::Clear([0.0; 4]))
            .color(t.depth, Load::Clear([0.0; 4]))
            .color(t.normal, Load::Clear([0.0; 4]))
            .depth(self.zbuffer, Load::Clear([0.0; 4]))
            .draw(move |ctx| ctx.draw(count.get(), 1));
        Ok(())
    }

    /// The three passes of the blended shadings: visibility, accumulation, normalization.
    fn blended(self, b: &mut BuildContext<'_>) -> Result<()> {
        let accum = |b: &mut BuildContext<'_>, name| {
            b.graph.image(
                name,
                ImageDesc {
                    format: ACCUM_FORMAT,
                    width: b.width,
                    height: b.height,
                    mip_levels: 1,
                    usage: vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::STORAGE,
                },
            )
        };
        let accum_color = accum(b, "splat.accum_color");
        let accum_normal = accum(b, "splat.accum_normal");
        let (binds, t) = (b.draw_binds(), b.targets);
        let count = b.scene.draw_points.clone();
        let visibility = self.desc(
            "splat/visibility.frag",
            &[DEPTH_FORMAT],
            Blend::Replace,
            true,
        );
        let points = count.clone();
        b.graph
            .draw("splat.visibility", visibility, &binds)
            .push(&self.params)
            .color(t.depth, Load::Clear([0.0; 4]))
            .depth(self.zbuffer, Load::Clear([0.0; 4]))
            .draw(move |ctx| ctx.draw(points.get(), 1));
        let accumulate = self.desc(
            "splat/accumulate.frag",
            &[ACCUM_FORMAT, ACCUM_FORMAT],
            Blend::Additive,
            false,
        );
        b.graph
            .draw("splat.accumulate", accumulate, &binds)
            .push(&self.params)
            .color(accum_color, Load::Clear([0.0; 4]))
            .color(accum_normal, Load::Clear([0.0; 4]))
            .depth(self.zbuffer, Load::Load)
            .draw(move |ctx| ctx.draw(count.get(), 1));
        let read = Access::StorageRead(Stages::Compute);
        let write = Access::StorageWrite(Stages::Compute);
        let normalize_binds = [
            Bind::constants(BINDING_FRAME, b.frame),
            Bind::image(BINDING_INPUT0, accum_color, 0, read),
            Bind::image(BINDING_INPUT1, accum_normal, 0, read),
            Bind::image(BINDING_INPUT2, t.depth, 0, read),
            Bind::image(BINDING_OUTPUT0, t.color, 0, write),
            Bind::image(BINDING_OUTPUT0 + 1, t.normal, 0, write),
        ];
        let groups = b.pixel_groups(RESOLVE_GROUP);
        b.graph
            .compute("splat.normalize", "splat/normalize.comp", &normalize_binds)
            .spec(&self.specialization)
            .dispatch_grid(groups);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_select_their_variants() {
        assert_eq!(
            variant("perspective-deferred").unwrap(),
            (SPLAT_RASTER_PERSPECTIVE, SPLAT_SHADING_DEFERRED)
        );
        assert_eq!(
            variant("points-flat").unwrap(),
            (SPLAT_RASTER_POINTS, SPLAT_SHADING_FLAT)
        );
        assert!(variant("discs-flat").is_err());
        assert!(variant("points").is_err());
    }
}

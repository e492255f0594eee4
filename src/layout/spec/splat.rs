//! The splatting family (002 sections 5.2-5.3, src/methods/splat).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Splatting family (src/methods/splat, 002 sections 5.2-5.3): specialization constant ids
    // and their values.
    ("SPLAT_SPEC_RASTER", 0),
    ("SPLAT_SPEC_SHADING", 1),
    ("SPLAT_SPEC_CULL", 2),
    ("SPLAT_RASTER_POINTS", 0),
    ("SPLAT_RASTER_SQUARES", 1),
    ("SPLAT_RASTER_AFFINE", 2),
    ("SPLAT_RASTER_PERSPECTIVE", 3),
    ("SPLAT_SHADING_FLAT", 0),
    ("SPLAT_SHADING_GOURAUD", 1),
    ("SPLAT_SHADING_PHONG", 2),
    ("SPLAT_SHADING_DEFERRED", 3),
];

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the splatting family (src/methods/splat).
    StructSpec {
        name: "SplatParams",
        doc: "Push constants of the splatting family (`SplatParams` in GLSL).",
        fields: &[
            // Scale of every point's radius (`radius` parameter).
            f("float", "radius_scale"),
            // Blending depth offset, relative to the linear depth (`epsilon` parameter).
            f("float", "epsilon"),
            // The device's largest point size: the sprite sizes are clamped to it.
            f("float", "max_point_size"),
            f("uint", "pad0"),
        ],
    },
];

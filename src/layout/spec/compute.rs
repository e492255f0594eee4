//! The compute rasterizer (src/methods/compute).

use super::StructSpec;

pub const CONSTANTS: &[(&str, u32)] = &[
    // Compute rasterizer (src/methods/compute): raster.comp and resolve.comp.
    ("RASTER_SPEC_MODE", 0),
    ("RASTER_SPEC_QUANTIZED", 1),
    ("RASTER_SPEC_CULL", 2),
    ("RASTER_SPEC_SKIP", 3),
    ("RESOLVE_SPEC_HIGH_QUALITY", 0),
];

pub const STRUCTS: &[StructSpec] = &[];

//! The viewer's text overlay (src/overlay).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Viewer text overlay: the per-slot glyph instances and the R8 glyph atlas (bytes packed
    // four to a word, row-major, OVERLAY_ATLAS_WIDTH texels per row).
    ("BINDING_OVERLAY_GLYPHS", 20),
    ("BINDING_OVERLAY_ATLAS", 21),
    ("OVERLAY_ATLAS_WIDTH", 512),
    // GpuGlyph.flags bits: a solid quad (panel background) instead of an atlas glyph.
    ("OVERLAY_SOLID", 1),
];

pub const STRUCTS: &[StructSpec] = &[
    // One overlay quad (a glyph or a panel background), in pixels. 32 bytes.
    StructSpec {
        name: "GpuGlyph",
        doc: "One overlay quad (`GpuGlyph` in GLSL): a glyph from the atlas or a solid panel.",
        fields: &[
            // Top-left and bottom-right corners in framebuffer pixels.
            f("vec4", "rect"),
            // Atlas texel of the glyph's top-left corner (1 texel = 1 pixel).
            f("uint", "atlas_x"),
            f("uint", "atlas_y"),
            // RGBA8, sRGB-encoded, straight alpha.
            f("uint", "color"),
            f("uint", "flags"),
        ],
    },
];

//! The post pass: eye-dome lighting and background (src/post).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    ("POST_GROUP", 8),
    // Eye-dome lighting samples this many neighbours on a circle (Potree, CloudCompare: 8).
    ("EDL_NEIGHBOURS", 8),
    // Specialization constant ids of the post pass (glsl/post/post.comp).
    ("POST_SPEC_EDL", 0),
    ("POST_SPEC_BACKGROUND", 1),
];

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the post-processing pass (eye-dome lighting, background).
    StructSpec {
        name: "PostParams",
        doc: "Push constants of the post-processing pass (`PostParams` in GLSL).",
        fields: &[
            // Integer pixel offsets of the EDL neighbours, two per vec4 (x0, y0, x1, y1).
            f("vec4", "offsets01"),
            f("vec4", "offsets23"),
            f("vec4", "offsets45"),
            f("vec4", "offsets67"),
            // sRGB-encoded background color, alpha 1.
            f("vec4", "background"),
            // EDL strength (the shade is exp(-300 strength sum / EDL_NEIGHBOURS)).
            f("float", "strength"),
            f("uint", "pad0"),
            f("uint", "pad1"),
            f("uint", "pad2"),
        ],
    },
];

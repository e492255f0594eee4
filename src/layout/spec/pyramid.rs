//! The pyramid point renderer (000 ch. 4-5, src/methods/pyramid).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Pyramid point renderer (000 ch. 4, src/methods/pyramid): the attribute groups of one
    // level are three storage images (A: normal.xyz, projected radius in level-0 pixels;
    // B: linear depth, depth-interval half range, displacement vector.xy in level-0 pixels;
    // C: linear albedo.rgb, primitive id). A pass reads the groups of up to two levels and
    // writes one: each takes three consecutive bindings.
    ("BINDING_PYRAMID_PARENT", 22),
    ("BINDING_PYRAMID_LEVEL", 25),
    ("BINDING_PYRAMID_OUT", 28),
    ("PYRAMID_GROUP", 8),
    // Specialization constant ids of the pyramid shaders and the primitive ids of group C.
    ("PYRAMID_SPEC_COLOR", 0),
    ("PYRAMID_SPEC_CULL", 1),
    // Hybrid scenes (000 5.2): level 0 holds rasterized triangles, then the points that are no
    // face's vertex (BINDING_FACE_VERTICES: one bit per point) where they are nearer.
    ("PYRAMID_SPEC_HYBRID", 2),
    // lines.vert draws tubes (true) or ribbons (false).
    ("PYRAMID_SPEC_TUBE", 3),
    ("BINDING_FACE_VERTICES", 15),
    ("PRIMITIVE_POINT", 0),
    ("PRIMITIVE_RIBBON", 1),
    ("PRIMITIVE_TUBE", 2),
    ("PRIMITIVE_TRIANGLE", 3),
];

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the pyramid passes (000 ch. 4, src/methods/pyramid).
    StructSpec {
        name: "PyramidParams",
        doc: "Push constants of the pyramid passes (`PyramidParams` in GLSL).",
        fields: &[
            // The level a pass writes (analysis: from level - 1; synthesis: from level + 1).
            f("uint", "level"),
            // Levels in the pyramid.
            f("uint", "level_count"),
            // Scale of the per-point radius (`radius` parameter).
            f("float", "radius_scale"),
            // Gaussian weight of the synthesis: exp(-falloff * d^2), d the distance to the
            // ellipse centre in units of the ellipse (1 on its rim).
            f("float", "falloff"),
        ],
    },
];

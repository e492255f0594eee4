// The single source of the bindings and struct layouts shared by GLSL and Rust.
// build.rs `include!`s this file to generate `shared.glsl` (the header every shader includes);
// the crate includes it too, and `gpu::layout` checks its `#[repr(C)]` mirrors against it.

/// One member of a shared struct: GLSL type and name. Only 4-byte scalars, vec2/vec4/uvec4 and
/// mat4 are allowed, so std430 and `#[repr(C)]` agree without hidden padding.
pub struct FieldSpec {
    pub ty: &'static str,
    pub name: &'static str,
}

/// A struct shared by GLSL (std430) and Rust.
pub struct StructSpec {
    pub name: &'static str,
    pub fields: &'static [FieldSpec],
}

const fn f(ty: &'static str, name: &'static str) -> FieldSpec {
    FieldSpec { ty, name }
}

/// Integer constants (`#define` in GLSL, `pub const` in Rust).
pub const CONSTANTS: &[(&str, u32)] = &[
    // Descriptor bindings (set 0, push descriptors).
    ("BINDING_FRAME", 0),
    ("BINDING_POINTS", 1),
    ("BINDING_INDICES", 2),
    ("BINDING_INPUT0", 3),
    ("BINDING_INPUT1", 4),
    ("BINDING_INPUT2", 5),
    ("BINDING_OUTPUT0", 6),
    // Frame output render targets (MRT locations).
    ("TARGET_COLOR", 0),
    ("TARGET_DEPTH", 1),
    ("TARGET_NORMAL", 2),
    // Light kinds (002 §4: attached to the camera, static in the world, orbiting the model).
    ("LIGHT_CAMERA", 0),
    ("LIGHT_STATIC", 1),
    ("LIGHT_ORBIT", 2),
    ("MAX_LIGHTS", 16),
    // FrameUniforms.flags bits.
    ("FLAG_USE_COLOR", 1),
    ("FLAG_HAS_NORMALS", 2),
    // Workgroup sizes.
    ("RESOLVE_GROUP", 8),
];

/// Structs shared between GLSL and Rust.
pub const STRUCTS: &[StructSpec] = &[
    // One point as stored on the GPU: 24 bytes. Position f32, octahedral normal (2 x snorm16),
    // radius as f16 in the low half of `radius_kind` (high half: primitive kind, 0 = point),
    // color RGBA8 (sRGB).
    StructSpec {
        name: "GpuPoint",
        fields: &[
            f("float", "x"),
            f("float", "y"),
            f("float", "z"),
            f("uint", "normal_oct"),
            f("uint", "radius_kind"),
            f("uint", "color"),
        ],
    },
    StructSpec {
        name: "GpuLight",
        fields: &[
            // xyz: view-space position (camera/static/orbit lights are resolved on the CPU).
            f("vec4", "position"),
            // rgb: intensity, a: kind.
            f("vec4", "color_kind"),
        ],
    },
    StructSpec {
        name: "FrameUniforms",
        fields: &[
            f("mat4", "view"),
            f("mat4", "proj"),
            f("mat4", "view_proj"),
            // x: width, y: height, z: 1/width, w: 1/height.
            f("vec4", "viewport"),
            // x: point size in pixels, y: near plane, z: ambient, w: specular exponent.
            f("vec4", "params"),
            f("vec4", "base_color"),
            f("uint", "flags"),
            f("uint", "light_count"),
            f("uint", "point_count"),
            f("uint", "pad0"),
        ],
    },
];

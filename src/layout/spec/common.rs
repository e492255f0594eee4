//! Shared by every family: the frame block, the point streams and their batches, targets, lights, color modes, classes and workgroup sizes.

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Workgroups per dimension every device accepts (maxComputeWorkGroupCount >= 65,535);
    // larger 1D dispatches fold into rows of this many (graph::bind::fold_groups on the host,
    // the indirect dispatch of glsl/hpr/frame.comp on the GPU).
    ("MAX_GROUPS", 65535),
    // Descriptor bindings (set 0, push descriptors).
    ("BINDING_FRAME", 0),
    ("BINDING_INDICES", 2),
    ("BINDING_INPUT0", 3),
    ("BINDING_INPUT1", 4),
    ("BINDING_INPUT2", 5),
    // Outputs take three consecutive bindings (color, depth, normal).
    ("BINDING_OUTPUT0", 6),
    // Point streams: the segment table (device addresses of every stream) and batch bounds.
    ("BINDING_SEGMENTS", 10),
    ("BINDING_BATCHES", 11),
    // Compute rasterizer: the 64-bit visibility buffer and the high-quality accumulators.
    ("BINDING_VISIBILITY", 12),
    ("BINDING_ACCUM", 13),
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
    ("FLAG_HAS_NORMALS", 2),
    // Attribute colors are shown as they are, without lighting (src/color.rs).
    ("FLAG_UNLIT", 4),
    // The clipping box applies (FrameUniforms.clip); with FLAG_CLIP_OUTSIDE it keeps the
    // points outside the box instead of inside.
    ("FLAG_CLIP", 8),
    ("FLAG_CLIP_OUTSIDE", 16),
    // Hidden classes apply (FrameUniforms.class_hidden_*, GpuSegment.classes).
    ("FLAG_FILTER", 32),
    // FrameUniforms.color_mode: what the albedo comes from (src/color.rs).
    ("COLOR_NONE", 0),
    ("COLOR_RGB", 1),
    ("COLOR_INTENSITY", 2),
    ("COLOR_SCALAR", 3),
    ("COLOR_CLASSIFICATION", 4),
    ("COLOR_RETURN", 5),
    ("COLOR_ELEVATION", 6),
    ("COLOR_NORMAL", 7),
    // ASPRS standard classes 0-18 (LAS 1.4 R15 table 17) as sRGB 0xRRGGBB, then any other class.
    ("CLASS_COLOR_0", 0x9e9e9e),
    ("CLASS_COLOR_1", 0xc8c8c8),
    ("CLASS_COLOR_2", 0xa0724a),
    ("CLASS_COLOR_3", 0x9bd77d),
    ("CLASS_COLOR_4", 0x4fa83c),
    ("CLASS_COLOR_5", 0x1e6e28),
    ("CLASS_COLOR_6", 0xdc5a46),
    ("CLASS_COLOR_7", 0xff00ff),
    ("CLASS_COLOR_8", 0xf0e650),
    ("CLASS_COLOR_9", 0x3c78e6),
    ("CLASS_COLOR_10", 0x8c5a3c),
    ("CLASS_COLOR_11", 0x5a5a5a),
    ("CLASS_COLOR_12", 0xd2d296),
    ("CLASS_COLOR_13", 0xfac800),
    ("CLASS_COLOR_14", 0xffa000),
    ("CLASS_COLOR_15", 0xaa3cc8),
    ("CLASS_COLOR_16", 0xf078c8),
    ("CLASS_COLOR_17", 0x78a0c8),
    ("CLASS_COLOR_18", 0xff0080),
    ("CLASS_COLOR_OTHER", 0xffffff),
    // Return numbers 1, 2, 3, 4 and 5 or later; 0 (invalid) takes RETURN_COLOR_0.
    ("RETURN_COLOR_0", 0x808080),
    ("RETURN_COLOR_1", 0xe63c3c),
    ("RETURN_COLOR_2", 0x3cb44b),
    ("RETURN_COLOR_3", 0x3c64e6),
    ("RETURN_COLOR_4", 0xf0c81e),
    ("RETURN_COLOR_5", 0xc850dc),
    // The scalar ramp (elevation and other scalars): blue, cyan, green, yellow, red, with
    // equal spacing, interpolated in sRGB.
    ("RAMP_0", 0x0000ff),
    ("RAMP_1", 0x00ffff),
    ("RAMP_2", 0x00ff00),
    ("RAMP_3", 0xffff00),
    ("RAMP_4", 0xff0000),
    // Workgroup sizes.
    ("RESOLVE_GROUP", 8),
    ("RASTER_GROUP", 128),
    // Points per batch (Schuetz et al. 2021: 10,240 points, 80 per thread of a 128-wide group).
    ("BATCH_POINTS", 10240),
    // Bits per axis of each quantized position word (Schuetz et al. 2022: 3 x 10 bits).
    ("QUANT_BITS", 10),
];

pub const STRUCTS: &[StructSpec] = &[
    // Bounds of one batch of Morton-ordered points and where its points are. 32 bytes.
    StructSpec {
        name: "GpuBatch",
        doc: "Bounds and point range of one batch (`GpuBatch` in GLSL).",
        fields: &[
            f("float", "min_x"),
            f("float", "min_y"),
            f("float", "min_z"),
            // Index of the batch's first point (global over all segments).
            f("uint", "first"),
            f("float", "max_x"),
            f("float", "max_y"),
            f("float", "max_z"),
            f("uint", "count"),
        ],
    },
    // One segment of the point streams: device addresses (lo, hi) of each stream's buffer.
    // Segments hold whole batches and stay below the device's buffer limits.
    StructSpec {
        name: "GpuSegment",
        doc: "Device addresses of one segment's streams (`GpuSegment` in GLSL), as (lo, hi) pairs.",
        fields: &[
            // xy: f32 xyz positions (12 B/point), zw: coarse quantized words (4 B/point).
            f("uvec4", "position_coarse"),
            // xy: medium quantized words, zw: fine quantized words (4 B/point each).
            f("uvec4", "medium_fine"),
            // xy: octahedral normals (4 B/point), zw: f16 radii packed in pairs (2 B/point).
            f("uvec4", "normal_radius"),
            // xy: RGBA8 colors (4 B/point), z: first point of the segment, w: scalar streams
            // (0 or 1).
            f("uvec4", "color_first"),
            // xy: the f32 stream of the one scalar field uploaded (the field colored by),
            // z: that field's index in the cloud, w: unused.
            f("uvec4", "scalar"),
            // xy: the linear normal fields of the Phong splats (8 B/point: the shape operator
            // [[a, b], [b, c]] times the splat radius as f16 a, b, c and a zero), zw: unused.
            f("uvec4", "normal_field"),
            // xy: classification classes, one byte per point, four per word (read while the
            // viewer hides classes), z: the field's index in the cloud, w: 1 when present.
            f("uvec4", "classes"),
        ],
    },
    StructSpec {
        name: "GpuLight",
        doc: "One light, resolved to view space on the CPU.",
        fields: &[
            // xyz: view-space position (camera/static/orbit lights are resolved on the CPU).
            f("vec4", "position"),
            // rgb: intensity, a: kind.
            f("vec4", "color_kind"),
        ],
    },
    StructSpec {
        name: "FrameUniforms",
        doc: "Per-frame uniforms.",
        fields: &[
            f("mat4", "view"),
            f("mat4", "proj"),
            f("mat4", "view_proj"),
            // x: width, y: height, z: 1/width, w: 1/height.
            f("vec4", "viewport"),
            // Fixed-size points' size in pixels.
            f("float", "point_size"),
            // The near plane's distance.
            f("float", "near"),
            // The ambient weight of the lighting.
            f("float", "ambient"),
            f("float", "specular_exponent"),
            f("vec4", "base_color"),
            f("uint", "flags"),
            f("uint", "light_count"),
            f("uint", "point_count"),
            // Points per stream segment (every segment but the last is full).
            f("uint", "segment_points"),
            f("uint", "batch_count"),
            // COLOR_*: where the albedo comes from (src/color.rs).
            f("uint", "color_mode"),
            // Specular weight; the albedo-tinted specular, the diffuse weight (1 - ambient -
            // specular) and the ambient sum to 1 at normal incidence, so colors stay true.
            f("float", "specular"),
            f("uint", "pad0"),
            // xyz: the up axis (COLOR_ELEVATION colors by position . axis), w: unused.
            f("vec4", "color_axis"),
            // x: the value at the ramp's start, y: 1 / (end - start), zw: unused.
            f("vec4", "color_range"),
            // Local position -> clipping-box unit coordinates (inside within +-1), read with
            // FLAG_CLIP (src/scene/clip.rs).
            f("mat4", "clip"),
            // Hidden classification classes 0-127 and 128-255, one bit each, read with
            // FLAG_FILTER.
            f("uvec4", "class_hidden_lo"),
            f("uvec4", "class_hidden_hi"),
        ],
    },
];

//! Hidden point removal on the GPU (003 ch. 4, src/methods/hpr).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Hidden point removal on the GPU (003 ch. 4, src/methods/hpr): one thread per point or
    // per sector in groups of HPR_GROUP; the bounding sphere, the per-frame sector frame
    // (HprFrame), the 64-bit extremes per sector ((DIST bits << 32) | ~index), the u32 extremes
    // a propagation round reads and writes, the coarse EMPTY grid, the hidden-point mask (one
    // bit per point, set = hidden), sort keys and values, the reconstruction's triangles and
    // the bounding sphere's per-workgroup partial sums.
    ("HPR_GROUP", 256),
    ("BINDING_HPR_SPHERE", 40),
    ("BINDING_HPR_FRAME", 41),
    ("BINDING_HPR_MAX", 42),
    ("BINDING_HPR_SRC", 43),
    ("BINDING_HPR_DST", 44),
    ("BINDING_HPR_EMPTY", 45),
    ("BINDING_HPR_MASK", 46),
    ("BINDING_HPR_KEYS", 47),
    ("BINDING_HPR_VALUES", 48),
    ("BINDING_HPR_TRIANGLES", 49),
    ("BINDING_HPR_PARTIALS", 50),
    // The complete visible set (beyond 003; src/hpr/prefilter.rs is its CPU reference): the
    // nearest point per sector as a 64-bit (distance bits, index) minimum on HPR_COMPLETE_LEVELS
    // grids, the finest first, each half as fine as the one before.
    ("BINDING_HPR_COMPLETE", 51),
    ("HPR_COMPLETE_LEVELS", 6),
    // Specialization constant ids: the sphere pass's step (HPR_SPHERE_*), the sector pass's
    // output (atomic maximum or sort keys), a propagation pass's gather reach (0: extract
    // only), whether it reads the 64-bit extremes, whether it flags changes (adaptive).
    ("HPR_SPEC_MODE", 0),
    ("HPR_SPEC_REACH", 1),
    ("HPR_SPEC_FROM_MAX", 2),
    ("HPR_SPEC_ADAPTIVE", 3),
    ("HPR_SPHERE_SUM", 0),
    ("HPR_SPHERE_CENTRE", 1),
    ("HPR_SPHERE_RADIUS", 2),
    ("HPR_SECTOR_ATOMIC", 0),
    ("HPR_SECTOR_SORT", 1),
    // No extreme in a sector.
    ("HPR_EMPTY", 0xffff_ffff),
];

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the HPR passes (src/methods/hpr).
    StructSpec {
        name: "HprParams",
        doc: "Push constants of the HPR passes (`HprParams` in GLSL).",
        fields: &[
            // √k of the sector buffers (the largest grid a frame may use).
            f("uint", "sqrt_k_max"),
            // √k requested; 0: from the viewport (one sector per pixel of the bounding
            // sphere's projection).
            f("uint", "sqrt_k"),
            f("uint", "point_count"),
            // Adaptive propagation: the most rounds recorded.
            f("uint", "max_rounds"),
            // R = `radius` (scene units) when > 0, else density x |C - C_e|^2 (R from the
            // sampling density and noise, src/hpr/mod.rs); raised to 1.01 x the farthest
            // point's distance.
            f("float", "radius"),
            f("float", "density"),
            // The complete visible set (src/hpr/prefilter.rs): sectors per angle of its
            // finest grid (a multiple of 2^(HPR_COMPLETE_LEVELS - 1)); 0: off.
            f("uint", "complete_side"),
            // Partial reconstruction: the longest projected edge kept, in pixels.
            f("float", "max_edge"),
        ],
    },
    // The per-frame HPR state (written by glsl/hpr/frame.comp, read by every later pass;
    // the dispatch and draw arguments are read indirectly).
    StructSpec {
        name: "HprFrame",
        doc: "The per-frame HPR state (`HprFrame` in GLSL).",
        fields: &[
            // Rows of the rotation from world (relative to the eye) to the sector frame.
            f("vec4", "axis_x"),
            f("vec4", "axis_y"),
            f("vec4", "axis_z"),
            // xyz: the eye, w: the flipping radius R.
            f("vec4", "eye_radius"),
            // x, y: the smallest phi and theta; z, w: a sector's size along them.
            f("vec4", "grid"),
            f("uint", "sqrt_k"),
            // 1: the full-sphere partition (phi wraps around).
            f("uint", "full"),
            // The EMPTY grid has one cell per coarse x coarse sectors, coarse_side per row.
            f("uint", "coarse"),
            f("uint", "coarse_side"),
            // Indirect dispatch of a propagation round (x = 0 once a round changed nothing).
            f("uint", "groups_x"),
            f("uint", "groups_y"),
            f("uint", "groups_z"),
            // Set by a propagation round that changed an extreme.
            f("uint", "changed"),
            // Propagation rounds that changed an extreme; visible points.
            f("uint", "rounds"),
            f("uint", "visible"),
            f("uint", "pad0"),
            f("uint", "pad1"),
            // VkDrawIndexedIndirectCommand of the reconstruction's triangles.
            f("uint", "index_count"),
            f("uint", "instance_count"),
            f("uint", "first_index"),
            f("uint", "vertex_offset"),
            f("uint", "first_instance"),
            f("uint", "pad2"),
            f("uint", "pad3"),
            f("uint", "pad4"),
        ],
    },
];

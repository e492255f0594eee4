//! Level of detail from object textures (000 ch. 7, src/methods/lod).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
    // Level of detail from object textures (000 ch. 7, src/lod): the patches (GpuLodPatch),
    // the object texture's vertices (GpuLodVertex), the list of selected vertex indices and
    // its counters (a VkDrawIndirectCommand, then the vertices selected per level). The
    // selection runs one thread per patch in groups of LOD_GROUP; LOD_MAX_LEVELS levels at
    // most (a patch's per-level counts and errors are one uvec4 and one vec4).
    ("BINDING_LOD_PATCHES", 52),
    ("BINDING_LOD_VERTICES", 53),
    ("BINDING_LOD_LIST", 54),
    ("BINDING_LOD_COUNTERS", 55),
    ("LOD_GROUP", 64),
    ("LOD_MAX_LEVELS", 4),
    // Splats colored by level (thesis Fig. 7.4: grey, yellow, blue, red for levels 0-3), sRGB.
    ("LOD_COLOR_0", 0x9e9e9e),
    ("LOD_COLOR_1", 0xf0c81e),
    ("LOD_COLOR_2", 0x3c64e6),
    ("LOD_COLOR_3", 0xe63c3c),
    // Specialization constant ids of the LOD draws: color by level (1) or the base color (0);
    // the mesh and geometry paths also append what they emit to the list (tests). Past the
    // splatting family's ids: the draws shade with splat/flat.frag, specialized by
    // SPLAT_SPEC_RASTER (squares or perspective-correct discs), which they read too.
    ("LOD_SPEC_COLOR_LEVELS", 8),
    ("LOD_SPEC_RECORD", 9),
    // The mesh path: a task workgroup chooses the levels of LOD_TASK_GROUP patches and
    // launches one mesh workgroup per patch, of LOD_PATCH_VERTICES threads (the most vertices
    // a level of a patch holds: 4^(LOD_MAX_LEVELS - 1)); the geometry path emits at most
    // LOD_PATCH_VERTICES points per patch.
    ("LOD_TASK_GROUP", 32),
    ("LOD_PATCH_VERTICES", 64),
    // The point budget: after the per-level counts the counters hold the threshold
    // the paths choose levels with (ε, or raised until the budget holds), the samples the
    // visible patches' coarsest levels draw, two pads, then LOD_BUDGET_BINS bins of the
    // samples each refinement adds, by the projected error demanding it: bin b holds errors
    // whose f32 bits >> 20 are LOD_BUDGET_BIN_BASE + b (8 bins per octave from 2^-16 pixels,
    // clamped at both ends). The threshold pass runs one workgroup of LOD_BUDGET_BINS threads.
    ("LOD_BUDGET_BINS", 256),
    ("LOD_BUDGET_BIN_BASE", 888),
    // Specialization constant id of the geometry path's vertices per invocation (its
    // declared output limit; the patch's level is split over LOD_PATCH_VERTICES / it
    // invocations).
    ("LOD_SPEC_GEOMETRY_CHUNK", 10),
];

pub const STRUCTS: &[StructSpec] = &[
    // One patch of the object texture (000 7.1): the representative splat, the per-level
    // errors and vertex counts, and where its vertices start. 80 bytes.
    StructSpec {
        name: "GpuLodPatch",
        doc: "One patch of the object texture (`GpuLodPatch` in GLSL).",
        fields: &[
            // xyz: the representative's centre, w: its radius.
            f("vec4", "sphere"),
            // xyz: the representative's unit normal, w: unused.
            f("vec4", "normal"),
            // The perpendicular error of each level (levels 1..l, so nondecreasing; 0 at
            // level 0); unused levels repeat the last.
            f("vec4", "errors"),
            // Vertices of each level (the representative's level holds 1; unused levels 0).
            f("uvec4", "counts"),
            // First vertex of the patch (the representative), coarsest level first.
            f("uint", "offset"),
            f("uint", "levels"),
            f("uint", "pad0"),
            f("uint", "pad1"),
        ],
    },
    // One vertex of the object texture. 32 bytes.
    StructSpec {
        name: "GpuLodVertex",
        doc: "One vertex of the object texture (`GpuLodVertex` in GLSL).",
        fields: &[
            // xyz: centre, w: radius.
            f("vec4", "sphere"),
            // x: octahedral unit normal, y: RGBA8 sRGB color (the mean of its points' colors),
            // z: the level, w: unused.
            f("uvec4", "normal_color"),
        ],
    },
    // Push constants of the LOD selection (src/lod/gpu.rs).
    StructSpec {
        name: "LodParams",
        doc: "Push constants of the LOD selection (`LodParams` in GLSL).",
        fields: &[
            // The threshold ε of the projected error, in pixels.
            f("float", "epsilon"),
            f("uint", "patch_count"),
            // The draw's largest point size in pixels.
            f("float", "max_point_size"),
            // The point budget: the most samples a frame projects (0: none).
            f("uint", "budget"),
        ],
    },
];

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
    ("POST_GROUP", 8),
    // Points per batch (Schuetz et al. 2021: 10,240 points, 80 per thread of a 128-wide group).
    ("BATCH_POINTS", 10240),
    // Bits per axis of each quantized position word (Schuetz et al. 2022: 3 x 10 bits).
    ("QUANT_BITS", 10),
    // Viewer text overlay: the per-slot glyph instances and the R8 glyph atlas (bytes packed
    // four to a word, row-major, OVERLAY_ATLAS_WIDTH texels per row).
    ("BINDING_OVERLAY_GLYPHS", 20),
    ("BINDING_OVERLAY_ATLAS", 21),
    ("OVERLAY_ATLAS_WIDTH", 512),
    // GpuGlyph.flags bits: a solid quad (panel background) instead of an atlas glyph.
    ("OVERLAY_SOLID", 1),
    // Eye-dome lighting samples this many neighbours on a circle (Potree, CloudCompare: 8).
    ("EDL_NEIGHBOURS", 8),
    // Specialization constant ids of the post pass (glsl/post/post.comp).
    ("POST_SPEC_EDL", 0),
    ("POST_SPEC_BACKGROUND", 1),
    // Compute rasterizer (src/methods/compute): raster.comp and resolve.comp.
    ("RASTER_SPEC_MODE", 0),
    ("RASTER_SPEC_QUANTIZED", 1),
    ("RASTER_SPEC_CULL", 2),
    ("RASTER_SPEC_SKIP", 3),
    ("RESOLVE_SPEC_HIGH_QUALITY", 0),
    // EWA splatting (src/methods/ewa): splat.comp and resolve.comp.
    ("EWA_SPEC_MODE", 0),
    ("EWA_SPEC_LARGE", 1),
    ("EWA_SPEC_SHADE_FRAGMENTS", 2),
    ("EWA_SPEC_COVERAGE", 0),
    ("EWA_SPEC_SHADED", 1),
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
    // EWA splatting (000 ch. 3): a resampling ellipse whose bounding box reaches further than
    // EWA_MAX_RADIUS pixels from its centre is rasterized by a whole workgroup (the large
    // splats' list at BINDING_EWA_LARGE) instead of one thread.
    ("EWA_MAX_RADIUS", 16),
    // Fixed-point scale of EWA's accumulated weights: a fragment of unit weight adds this much
    // (a pixel's sums overflow past 2^32 / EWA_WEIGHT_SCALE = 262,144 unit-weight fragments).
    ("EWA_WEIGHT_SCALE", 16384),
    ("BINDING_EWA_LARGE", 14),
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
    // The pyramid with search kernels (000 ch. 6, src/methods/pyramid/kernel.rs): the kernel
    // size k (3, 5 or 7) as a specialization constant, and the per-pixel accumulators of the
    // interpolation passes at three consecutive bindings (RGBA32F: sum of w n and of w; sums of
    // w depth and w radius, the front-most contribution's depth and half range; sum of w albedo).
    ("PYRAMID_SPEC_KERNEL", 4),
    ("BINDING_KERNEL_ACCUM", 16),
    ("PRIMITIVE_POINT", 0),
    ("PRIMITIVE_RIBBON", 1),
    ("PRIMITIVE_TUBE", 2),
    ("PRIMITIVE_TRIANGLE", 3),
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
    // GPU radix sort and segmented maximum (src/methods/hpr/sort.rs): bindings of the keys and
    // values read and written, the digit histogram and the scan's block sums.
    ("BINDING_SORT_KEYS", 32),
    ("BINDING_SORT_VALUES", 33),
    ("BINDING_SORT_KEYS_OUT", 34),
    ("BINDING_SORT_VALUES_OUT", 35),
    ("BINDING_SORT_HIST", 36),
    ("BINDING_SORT_SUMS", 37),
    // Bits per digit and digits (histogram bins) per pass.
    ("SORT_DIGIT_BITS", 8),
    ("SORT_RADIX", 256),
    // Count and scatter: SORT_GROUP threads, SORT_ITEMS elements each per tile.
    ("SORT_GROUP", 128),
    ("SORT_ITEMS", 8),
    // Scan: SCAN_GROUP threads, SCAN_ITEMS consecutive entries each per block.
    ("SCAN_GROUP", 256),
    ("SCAN_ITEMS", 4),
    // Segmented maximum: one element per thread, SEGMAX_GROUP elements per tile.
    ("SEGMAX_GROUP", 256),
    // Specialization constant id of the scatter's subgroups per workgroup.
    ("SORT_SPEC_SUBGROUPS", 0),
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
    // k-NN normals and radii on the GPU (src/estimate): the input positions (three floats per
    // point), the cell key and value (input index in the low word) of every point, sorted by
    // the radix sort at its own bindings, the first and end sorted index of every hash bucket
    // (uvec2), the sorted points (xyz, w: the input index's bits) and the result per input
    // point (xyz: oriented normal, w: squared k-th neighbour distance, < 0 unresolved), and
    // each point's KNN_GRAPH_K nearest neighbours as input indices (0xffffffff past the last;
    // the orientation's propagation graph, scene::orient). One thread per point in groups of
    // KNN_GROUP; the neighbourhood size is the specialization constant KNN_SPEC_K (KNN_MAX_K
    // at most: each thread keeps its k best in registers).
    ("BINDING_KNN_POSITIONS", 56),
    ("BINDING_KNN_TABLE", 57),
    ("BINDING_KNN_SORTED", 58),
    ("BINDING_KNN_OUT", 59),
    ("BINDING_KNN_GRAPH", 60),
    ("KNN_GRAPH_K", 6),
    ("KNN_GROUP", 64),
    ("KNN_MAX_K", 32),
    ("KNN_SPEC_K", 0),
];

/// Structs shared between GLSL and Rust.
pub const STRUCTS: &[StructSpec] = &[
    // Bounds of one batch of Morton-ordered points and where its points are. 32 bytes.
    StructSpec {
        name: "GpuBatch",
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
            // x: point size in pixels, y: near plane, z: ambient weight, w: specular exponent.
            f("vec4", "params"),
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
    // One overlay quad (a glyph or a panel background), in pixels. 32 bytes.
    StructSpec {
        name: "GpuGlyph",
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
    // Push constants of the post-processing pass (eye-dome lighting, background).
    StructSpec {
        name: "PostParams",
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
    // Push constants of the splatting family (src/methods/splat).
    StructSpec {
        name: "SplatParams",
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
    // Push constants of the EWA splatting passes (000 ch. 3, src/methods/ewa).
    StructSpec {
        name: "EwaParams",
        fields: &[
            // Scale of the per-point radius: the reconstruction kernel's standard deviation
            // in object space is radius * stream_radius (V_r = r^2 I, eq. 3.30).
            f("float", "radius"),
            // The Gaussian is truncated at this many standard deviations (Mahalanobis
            // distance of the resampling filter).
            f("float", "cutoff"),
            // Standard deviation of the screen-space prefilter in pixels (V_h, eq. 3.31).
            f("float", "prefilter"),
            // Half-width of a fragment's depth interval in units of the splat's standard
            // deviation (the adaptive interval of 3.2.3).
            f("float", "interval"),
        ],
    },
    // Push constants of the pyramid passes (000 ch. 4, src/methods/pyramid).
    StructSpec {
        name: "PyramidParams",
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
    // Push constants of the GPU k-NN passes (src/estimate).
    StructSpec {
        name: "KnnParams",
        fields: &[
            // xyz: the grid's origin, w: its cell edge.
            f("vec4", "origin_cell"),
            // xyz: cells per axis, w: points.
            f("uvec4", "dims_count"),
            // xyz: the sensor, w: 1 when normals point towards it, 0 when away from the
            // centroid.
            f("vec4", "sensor"),
            // xyz: the finite points' centroid.
            f("vec4", "mean"),
            // Bits of a hash bucket (2^bits buckets).
            f("uint", "hash_bits"),
            f("uint", "pad0"),
            f("uint", "pad1"),
            f("uint", "pad2"),
        ],
    },
    // Push constants of the HPR passes (src/methods/hpr).
    StructSpec {
        name: "HprParams",
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
    // One patch of the object texture (000 7.1): the representative splat, the per-level
    // errors and vertex counts, and where its vertices start. 80 bytes.
    StructSpec {
        name: "GpuLodPatch",
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

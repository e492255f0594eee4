//! k-NN normals and radii on the GPU (src/estimate).

use super::{f, StructSpec};

pub const CONSTANTS: &[(&str, u32)] = &[
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

pub const STRUCTS: &[StructSpec] = &[
    // Push constants of the GPU k-NN passes (src/estimate).
    StructSpec {
        name: "KnnParams",
        doc: "Push constants of the GPU k-NN passes (`KnnParams` in GLSL).",
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
];

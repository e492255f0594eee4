// Shared by the k-NN passes (src/estimate): push constants, the grid's cells and their hash
// buckets.
#include "shared.glsl"

layout(push_constant) uniform Push {
    KnnParams p;
};

layout(local_size_x = KNN_GROUP) in;

// This thread's point: dispatches past 65,535 workgroups fold into rows of
// gl_NumWorkGroups.x groups.
uint thread_index() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * KNN_GROUP;
}

bool finite3(vec3 v) {
    return !any(isnan(v)) && !any(isinf(v));
}

// The cell of a finite point, clamped to the grid as on the CPU (GridFrame::cell_of in
// src/scene/knn.rs).
ivec3 cell_of(vec3 q) {
    vec3 c = floor((q - p.origin_cell.xyz) / p.origin_cell.w);
    return ivec3(clamp(c, vec3(0.0), vec3(p.dims_count.xyz - 1u)));
}

// The hash bucket of cell `c`: the three coordinates mixed by large odd multipliers, then the
// high `hash_bits` bits of a Fibonacci hash. Cells sharing a bucket only add candidates: the
// search measures every candidate's distance.
uint bucket_of(ivec3 c) {
    uint h = (uint(c.x) * 73856093u) ^ (uint(c.y) * 19349663u) ^ (uint(c.z) * 83492791u);
    return (h * 2654435769u) >> (32u - p.hash_bits);
}

#version 460
// k-NN, first pass: every point's sort key is the hash bucket of its cell and its value its
// input index, for the radix sort to group the points by bucket.
#include "knn.glsl"

layout(std430, set = 0, binding = BINDING_KNN_POSITIONS) readonly buffer Positions {
    float positions[];
};
layout(std430, set = 0, binding = BINDING_SORT_KEYS) writeonly buffer Keys {
    uint keys[];
};
layout(std430, set = 0, binding = BINDING_SORT_VALUES) writeonly buffer Values {
    uvec2 values[];
};

void main() {
    uint i = thread_index();
    if (i >= p.dims_count.w) {
        return;
    }
    vec3 q = vec3(positions[3u * i], positions[3u * i + 1u], positions[3u * i + 2u]);
    // Non-finite points join bucket 0; their distances are never finite, so no search keeps
    // them.
    keys[i] = finite3(q) ? bucket_of(cell_of(q)) : 0u;
    values[i] = uvec2(i, 0u);
}

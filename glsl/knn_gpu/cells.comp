#version 460
// k-NN, after the sort: each bucket's first and end index in the sorted order (the table is
// cleared to zeros before, so empty buckets hold none), and the points in sorted order with
// their input index, for the search to read contiguous candidates.
#include "knn.glsl"

layout(std430, set = 0, binding = BINDING_KNN_POSITIONS) readonly buffer Positions {
    float positions[];
};
layout(std430, set = 0, binding = BINDING_SORT_KEYS) readonly buffer Keys {
    uint keys[];
};
layout(std430, set = 0, binding = BINDING_SORT_VALUES) readonly buffer Values {
    uvec2 values[];
};
// Bucket b: [2 b] first sorted index, [2 b + 1] end.
layout(std430, set = 0, binding = BINDING_KNN_TABLE) writeonly buffer Table {
    uint table[];
};
// xyz: position, w: the input index's bits.
layout(std430, set = 0, binding = BINDING_KNN_SORTED) writeonly buffer Sorted {
    vec4 sorted[];
};

void main() {
    uint s = thread_index();
    uint n = p.dims_count.w;
    if (s >= n) {
        return;
    }
    uint key = keys[s];
    if (s == 0u || keys[s - 1u] != key) {
        table[2u * key] = s;
    }
    if (s + 1u == n || keys[s + 1u] != key) {
        table[2u * key + 1u] = s + 1u;
    }
    uint i = values[s].x;
    vec3 q = vec3(positions[3u * i], positions[3u * i + 1u], positions[3u * i + 2u]);
    sorted[s] = vec4(q, uintBitsToFloat(i));
}

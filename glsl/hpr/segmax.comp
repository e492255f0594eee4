#version 460
// Segmented maximum over keys sorted ascending: maxima[s] = max(values[i] for keys[i] == s).
//
// One tile of SEGMAX_GROUP elements per workgroup, one element per thread. A segmented
// inclusive max-scan in shared memory (Hillis-Steele; an element combines with the one `step`
// before it only when their keys are equal, which in sorted keys means the whole span between
// them is one segment) leaves each segment's tile-local maximum at its last element in the
// tile (where the next key differs, or at the tile's end).
//   * A segment lying entirely inside the tile belongs to this workgroup alone: a plain store.
//   * A segment crossing the tile's first or last element (at most two per tile) is split
//     between workgroups: every part combines with a 64-bit atomicMax
//     (GL_EXT_shader_atomic_int64, shaderBufferInt64Atomics), so the caller clears maxima to 0.
// Keys without elements are left untouched.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "sort.glsl"

layout(local_size_x = SEGMAX_GROUP) in;

layout(std430, set = 0, binding = BINDING_SORT_KEYS) readonly buffer Keys { uint keys[]; };
layout(std430, set = 0, binding = BINDING_SORT_VALUES) readonly buffer Values {
    uint64_t values[];
};
layout(std430, set = 0, binding = BINDING_SORT_VALUES_OUT) buffer Maxima { uint64_t maxima[]; };

shared uint tile_keys[SEGMAX_GROUP];
shared uint64_t tile_max[SEGMAX_GROUP];

void main() {
    uint tile = group_index();
    uint start = tile * SEGMAX_GROUP;
    if (start >= pc.count) {
        return;
    }
    uint t = gl_LocalInvocationIndex;
    uint n = min(SEGMAX_GROUP, pc.count - start);
    bool valid = t < n;
    // Threads past the end hold key 0, but only ever read lower threads: no valid element
    // combines with them.
    uint key = valid ? keys[start + t] : 0;
    uint64_t m = valid ? values[start + t] : 0ul;
    tile_keys[t] = key;
    tile_max[t] = m;
    barrier();
    for (uint step = 1; step < SEGMAX_GROUP; step <<= 1) {
        if (t >= step && tile_keys[t - step] == key) {
            m = max(m, tile_max[t - step]);
        }
        barrier();
        tile_max[t] = m;
        barrier();
    }
    bool last = t == n - 1;
    if (!valid || (!last && tile_keys[t + 1] == key)) {
        return;
    }
    bool crosses_start = start > 0 && tile_keys[0] == key && keys[start - 1] == key;
    bool crosses_end = last && start + n < pc.count && keys[start + n] == key;
    if (crosses_start || crosses_end) {
        atomicMax(maxima[key], m);
    } else {
        maxima[key] = m;
    }
}

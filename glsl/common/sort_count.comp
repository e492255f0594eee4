#version 460
// Radix sort, pass (a) of each digit: the digit histogram of one tile of SORT_GROUP *
// SORT_ITEMS keys, counted with shared-memory atomics and written digit-major
// (hist[digit * tiles + tile]), so one exclusive prefix sum over the whole array gives every
// (digit, tile) its first output position.
#include "sort.glsl"

layout(local_size_x = SORT_GROUP) in;

layout(std430, set = 0, binding = BINDING_SORT_KEYS) readonly buffer Keys { uint keys[]; };
layout(std430, set = 0, binding = BINDING_SORT_HIST) writeonly buffer Hist { uint hist[]; };

shared uint counts[SORT_RADIX];

void main() {
    uint tile = group_index();
    if (tile >= pc.tiles) {
        return;
    }
    uint t = gl_LocalInvocationIndex;
    for (uint d = t; d < SORT_RADIX; d += SORT_GROUP) {
        counts[d] = 0;
    }
    barrier();
    uint start = tile * SORT_GROUP * SORT_ITEMS;
    for (uint k = 0; k < SORT_ITEMS; ++k) {
        uint i = start + k * SORT_GROUP + t;
        if (i < pc.count) {
            atomicAdd(counts[digit_of(keys[i])], 1);
        }
    }
    barrier();
    for (uint d = t; d < SORT_RADIX; d += SORT_GROUP) {
        hist[d * pc.tiles + tile] = counts[d];
    }
}

#version 460
// Radix sort scan, step 1 (reduce): the sum of each block of SCAN_BLOCK histogram entries.
#include "scan.glsl"

layout(std430, set = 0, binding = BINDING_SORT_HIST) readonly buffer Hist { uint hist[]; };
layout(std430, set = 0, binding = BINDING_SORT_SUMS) writeonly buffer Sums { uint sums[]; };

void main() {
    uint block = group_index();
    if (block >= pc.blocks) {
        return;
    }
    uint entries = pc.tiles * SORT_RADIX;
    uint first = block * SCAN_BLOCK + gl_LocalInvocationIndex * SCAN_ITEMS;
    uint sum = 0;
    for (uint k = 0; k < SCAN_ITEMS; ++k) {
        uint i = first + k;
        sum += i < entries ? hist[i] : 0;
    }
    uint total;
    scan_exclusive(sum, total);
    if (gl_LocalInvocationIndex == 0) {
        sums[block] = total;
    }
}

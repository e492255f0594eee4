#version 460
// Radix sort scan, step 3 (downsweep): each block scans its SCAN_BLOCK histogram entries in
// place and adds its block's offset (the scanned block sum), completing the exclusive prefix
// sum over the whole histogram.
#include "scan.glsl"

layout(std430, set = 0, binding = BINDING_SORT_HIST) buffer Hist { uint hist[]; };
layout(std430, set = 0, binding = BINDING_SORT_SUMS) readonly buffer Sums { uint sums[]; };

void main() {
    uint block = group_index();
    if (block >= pc.blocks) {
        return;
    }
    uint entries = pc.tiles * SORT_RADIX;
    uint first = block * SCAN_BLOCK + gl_LocalInvocationIndex * SCAN_ITEMS;
    uint items[SCAN_ITEMS];
    uint sum = 0;
    for (uint k = 0; k < SCAN_ITEMS; ++k) {
        uint i = first + k;
        items[k] = i < entries ? hist[i] : 0;
        sum += items[k];
    }
    uint total;
    uint run = sums[block] + scan_exclusive(sum, total);
    for (uint k = 0; k < SCAN_ITEMS; ++k) {
        uint i = first + k;
        if (i < entries) {
            hist[i] = run;
        }
        run += items[k];
    }
}

#version 460
// Radix sort scan, step 2: the exclusive prefix sum of the block sums, in place, by a single
// workgroup looping over them in chunks of SCAN_BLOCK with a running carry. No workgroup ever
// waits for another (lavapipe gives no forward-progress guarantee between workgroups).
#include "scan.glsl"

layout(std430, set = 0, binding = BINDING_SORT_SUMS) buffer Sums { uint sums[]; };

void main() {
    uint carry = 0;
    for (uint base = 0; base < pc.blocks; base += SCAN_BLOCK) {
        uint first = base + gl_LocalInvocationIndex * SCAN_ITEMS;
        uint items[SCAN_ITEMS];
        uint sum = 0;
        for (uint k = 0; k < SCAN_ITEMS; ++k) {
            uint i = first + k;
            items[k] = i < pc.blocks ? sums[i] : 0;
            sum += items[k];
        }
        uint total;
        uint run = carry + scan_exclusive(sum, total);
        for (uint k = 0; k < SCAN_ITEMS; ++k) {
            uint i = first + k;
            if (i < pc.blocks) {
                sums[i] = run;
            }
            run += items[k];
        }
        carry += total;
    }
}

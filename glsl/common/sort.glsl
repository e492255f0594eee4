// Shared by the radix sort and segmented maximum shaders (src/methods/hpr/sort.rs).
#include "shared.glsl"

layout(push_constant) uniform Push {
    // Elements to sort (or to reduce, for the segmented maximum).
    uint count;
    // This digit pass's lowest key bit and its digit mask (the bits of `key_bits` it covers).
    uint shift;
    uint mask;
    // Tiles of SORT_GROUP * SORT_ITEMS elements; the histogram holds SORT_RADIX * tiles
    // entries, digit-major (hist[digit * tiles + tile]).
    uint tiles;
    // Scan blocks of SCAN_GROUP * SCAN_ITEMS histogram entries.
    uint blocks;
} pc;

// The workgroup's index in a dispatch folded into 2D past the 65,535 groups per dimension
// every device allows (the host rounds up: callers skip indices past their group count).
uint group_index() {
    return gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
}

// The digit of `key` in this pass.
uint digit_of(uint key) {
    return (key >> pc.shift) & pc.mask;
}

#version 460
// The complete visible set, one coarser grid: each sector keeps the nearest of its four
// children's points.
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

// This grid's level (1 .. HPR_COMPLETE_LEVELS - 1).
layout(constant_id = HPR_SPEC_MODE) const uint LEVEL = 1;

layout(std430, set = 0, binding = BINDING_HPR_COMPLETE) buffer Nearest {
    uint64_t nearest[];
};

void main() {
    uint t = thread_id();
    uint s = p.complete_side >> LEVEL;
    if (t >= s * s) {
        return;
    }
    uint fine = s * 2u;
    uint base = complete_offset(LEVEL - 1u);
    uint i = t / s;
    uint j = t % s;
    uint64_t best = nearest[base + 2u * i * fine + 2u * j];
    best = min(best, nearest[base + 2u * i * fine + 2u * j + 1u]);
    best = min(best, nearest[base + (2u * i + 1u) * fine + 2u * j]);
    best = min(best, nearest[base + (2u * i + 1u) * fine + 2u * j + 1u]);
    nearest[complete_offset(LEVEL) + t] = best;
}

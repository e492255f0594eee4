#version 460
// The point budget's first pass: one thread per patch in view adds its coarsest
// level's samples to `budget_base` and, for each finer level l - 1, the samples refining to it
// adds (counts[l - 1] - counts[l]) to the bin of the projected error e_l that demands it.
// Only errors above ε count: below it the finer level is drawn whatever the budget.
// `ObjectTexture::budget_threshold` is the CPU reference.
#include "lod.glsl"

layout(local_size_x = LOD_GROUP) in;

layout(std430, set = 0, binding = BINDING_LOD_PATCHES) readonly buffer Patches {
    GpuLodPatch patches[];
};
layout(std430, set = 0, binding = BINDING_LOD_COUNTERS) buffer Counters {
    LOD_COUNTERS_MEMBERS
};

layout(push_constant) uniform Push { LodParams pc; };

void main() {
    uint p = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * LOD_GROUP;
    if (p >= pc.patch_count) {
        return;
    }
    GpuLodPatch rep = patches[p];
    if (!lod_in_view(rep)) {
        return;
    }
    uint top = rep.levels - 1u;
    atomicAdd(budget_base, rep.counts[top]);
    float scale = lod_scale(rep);
    for (uint l = top; l > 0u; --l) {
        float e = rep.errors[l] * scale;
        if (e > pc.epsilon) {
            atomicAdd(bins[lod_budget_bin(e)], rep.counts[l - 1u] - rep.counts[l]);
        }
    }
}

#version 460
// The compute expansion of level of detail (000 7.2): one thread per patch chooses its level
// and appends that level's vertex indices to a list, counting them in an indirect draw's
// vertex count and per level.
#include "lod.glsl"

layout(local_size_x = LOD_GROUP) in;

layout(std430, set = 0, binding = BINDING_LOD_PATCHES) readonly buffer Patches {
    GpuLodPatch patches[];
};
layout(std430, set = 0, binding = BINDING_LOD_LIST) writeonly buffer List { uint list[]; };
// draw: a VkDrawIndirectCommand (vertex count, instance count 1, 0, 0).
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
    uint level = lod_level(rep, threshold);
    uint count = rep.counts[level];
    uint first = lod_level_offset(rep, level);
    uint base = atomicAdd(draw[0], count);
    atomicAdd(per_level[level], count);
    for (uint k = 0u; k < count; ++k) {
        list[base + k] = first + k;
    }
}

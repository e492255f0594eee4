#version 460
// The geometry expansion's draw (000 7.2): the geometry shader chooses the patch's level and
// emits that level's vertices, fetched from the object texture, as points (at most
// LOD_PATCH_VERTICES, within every device's maxGeometryOutputVertices and total output
// components), split over invocations of CHUNK vertices each (the output-limit study). It
// adds its count to the counters; under RECORD it also appends the emitted vertex indices to
// the list (tests).
#include "lod.glsl"

// The declared limits: `GraphicsDesc::geometry_output` rewrites both literals of the SPIR-V
// (LOD_PATCH_VERTICES / CHUNK invocations of CHUNK vertices each).
layout(points, invocations = 1) in;
layout(points, max_vertices = LOD_PATCH_VERTICES) out;

layout(constant_id = LOD_SPEC_COLOR_LEVELS) const bool COLOR_LEVELS = false;
layout(constant_id = LOD_SPEC_RECORD) const bool RECORD = false;
// Vertices one invocation emits: invocation i emits the level's [i CHUNK, (i + 1) CHUNK).
layout(constant_id = LOD_SPEC_GEOMETRY_CHUNK) const uint CHUNK = LOD_PATCH_VERTICES;

layout(std430, set = 0, binding = BINDING_LOD_PATCHES) readonly buffer Patches {
    GpuLodPatch patches[];
};
layout(std430, set = 0, binding = BINDING_LOD_VERTICES) readonly buffer Vertices {
    GpuLodVertex vertices[];
};
layout(std430, set = 0, binding = BINDING_LOD_LIST) writeonly buffer List { uint list[]; };
layout(std430, set = 0, binding = BINDING_LOD_COUNTERS) buffer Counters {
    LOD_COUNTERS_MEMBERS
};

layout(push_constant) uniform Push { LodParams pc; };

layout(location = 0) flat in uint v_patch[];

layout(location = 0) flat out vec3 v_color;
layout(location = 1) flat out vec3 v_normal;
layout(location = 2) flat out vec3 v_centre;
layout(location = 3) flat out float v_radius;
layout(location = 4) flat out float v_size;

void main() {
    GpuLodPatch rep = patches[v_patch[0]];
    if (!lod_in_view(rep)) {
        return;
    }
    uint level = lod_level(rep, threshold);
    uint count = rep.counts[level];
    uint first = lod_level_offset(rep, level);
    uint begin = uint(gl_InvocationID) * CHUNK;
    if (begin >= count) {
        return;
    }
    uint end = min(count, begin + CHUNK);
    if (begin == 0u) {
        atomicAdd(per_level[level], count);
    }
    uint base = RECORD ? atomicAdd(draw[0], end - begin) - begin : 0u;
    for (uint k = begin; k < end; ++k) {
        if (RECORD) {
            list[base + k] = first + k;
        }
        LodSplat o = lod_splat(vertices[first + k], pc.max_point_size, COLOR_LEVELS);
        gl_Position = o.position;
        gl_PointSize = o.size;
        v_color = o.color;
        v_normal = o.normal;
        v_centre = o.centre;
        v_radius = o.radius;
        v_size = o.size;
        EmitVertex();
    }
}

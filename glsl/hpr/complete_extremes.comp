#version 460
// The complete visible set, per point: the nearest point (to the eye; its flipped image is
// the farthest) of each sector of the finest grid, as a 64-bit minimum of (distance bits,
// index): non-negative floats order as their bits, ties go to the lower index.
#extension GL_EXT_shader_atomic_int64 : require
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(std430, set = 0, binding = BINDING_HPR_COMPLETE) buffer Nearest {
    uint64_t nearest[];
};

void main() {
    uint i = thread_id();
    if (i >= p.point_count) {
        return;
    }
    vec3 local = stream_position(i);
    vec3 v = local - h.eye_radius.xyz;
    float n = length(v);
    if (n == 0.0 || !point_kept(i, local)) {
        return;
    }
    uvec2 c = complete_cell(v, n);
    uint64_t key = (uint64_t(floatBitsToUint(n)) << 32) | uint64_t(i);
    atomicMin(nearest[c.x * p.complete_side + c.y], key);
}

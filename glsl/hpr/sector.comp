#version 460
// Per point (003 4.2): the point relative to the eye, its sector (i along phi, j along theta)
// and DIST along the sector's direction; marks the point's EMPTY cell occupied. Then either
// the sort-free extreme (a 64-bit atomicMax of (DIST, ~index) per sector) or the sort input
// (key: sector id, value: the same 64-bit key) for the thesis' radix sort and segmented
// maximum. Points at the eye cannot be flipped: no sector (the sort gets the sentinel key
// k_max, past every sector).
#extension GL_EXT_shader_atomic_int64 : require
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(constant_id = HPR_SPEC_MODE) const uint MODE = HPR_SECTOR_ATOMIC;

layout(std430, set = 0, binding = BINDING_HPR_MAX) buffer Extremes {
    uint64_t extremes[];
};
layout(std430, set = 0, binding = BINDING_HPR_EMPTY) writeonly buffer Occupied {
    uint occupied[];
};
layout(std430, set = 0, binding = BINDING_HPR_KEYS) writeonly buffer Keys {
    uint keys[];
};
layout(std430, set = 0, binding = BINDING_HPR_VALUES) writeonly buffer Values {
    uint64_t values[];
};

void main() {
    uint i = thread_id();
    if (i >= p.point_count) {
        return;
    }
    vec3 local = stream_position(i);
    vec3 v = local - h.eye_radius.xyz;
    float n = length(v);
    // A point the viewer's filter hides takes no part, like one at the eye.
    if (n == 0.0 || !point_kept(i, local)) {
        if (MODE == HPR_SECTOR_SORT) {
            keys[i] = p.sqrt_k_max * p.sqrt_k_max;
            values[i] = 0ul;
        }
        return;
    }
    vec3 l = vec3(dot(h.axis_x.xyz, v), dot(h.axis_y.xyz, v), dot(h.axis_z.xyz, v));
    float phi = atan(l.y, l.x);
    float theta = acos(clamp(l.z / n, -1.0, 1.0));
    float last = float(h.sqrt_k - 1u);
    uint si = uint(clamp(floor((phi - h.grid.x) / h.grid.z), 0.0, last));
    uint sj = uint(clamp(floor((theta - h.grid.y) / h.grid.w), 0.0, last));
    uint id = si * h.sqrt_k + sj;
    occupied[empty_cell(si, sj)] = 1u;
    uint64_t key = extreme_key(dist_along(v, n, sector_dir(si, sj)), i);
    if (MODE == HPR_SECTOR_ATOMIC) {
        atomicMax(extremes[id], key);
    } else {
        keys[i] = id;
        values[i] = key;
    }
}

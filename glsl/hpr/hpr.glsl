// Hidden point removal on the GPU (003 ch. 4): the sector frame, the flip's DIST and the
// 64-bit extreme keys shared by the HPR passes (src/methods/hpr; the CPU reference is
// src/hpr/approx.rs, operation for operation).
#ifndef SURFEL_HPR_GLSL
#define SURFEL_HPR_GLSL
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "streams.glsl"

layout(push_constant) uniform Push {
    HprParams p;
};

// The bounding sphere: centre and the radius' bits (non-negative floats order as uints, so
// the radius pass takes an atomic maximum of them). Writable only where HPR_WRITES_SPHERE is
// defined (validation counts every store a shader holds as an access).
#ifdef HPR_WRITES_SPHERE
layout(std430, set = 0, binding = BINDING_HPR_SPHERE) buffer Sphere {
#else
layout(std430, set = 0, binding = BINDING_HPR_SPHERE) readonly buffer Sphere {
#endif
    vec3 sphere_centre;
    uint sphere_radius_bits;
};

// The per-frame state, writable only where HPR_WRITES_STATE is defined.
#ifdef HPR_WRITES_STATE
layout(std430, set = 0, binding = BINDING_HPR_FRAME) buffer State {
#else
layout(std430, set = 0, binding = BINDING_HPR_FRAME) readonly buffer State {
#endif
    HprFrame h;
};

// The thread of a 1D dispatch folded into 2D (at most 32,768 groups per row).
uint thread_id() {
    return (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * HPR_GROUP
        + gl_LocalInvocationID.x;
}

// DIR of sector (i, j): the direction of its bisectors, in world orientation.
vec3 sector_dir(uint i, uint j) {
    float phi = h.grid.x + (float(i) + 0.5) * h.grid.z;
    float theta = h.grid.y + (float(j) + 0.5) * h.grid.w;
    vec3 l = vec3(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
    return h.axis_x.xyz * l.x + h.axis_y.xyz * l.y + h.axis_z.xyz * l.z;
}

// DIST - 2R of the point at v (relative to the eye, |v| = n) along the unit direction d:
// -(|p| + (2R - |p|) |u - d|^2 / 2), the flipped point's projection on d less 2R, in a form
// where the angular term survives f32 (src/hpr/approx.rs).
float dist_along(vec3 v, float n, vec3 d) {
    vec3 e = v / n - d;
    return -(n + (2.0 * h.eye_radius.w - n) * (0.5 * dot(e, e)));
}

// DIST - 2R of point `i` along d.
float point_along(uint i, vec3 d) {
    vec3 v = stream_position(i) - h.eye_radius.xyz;
    return dist_along(v, length(v), d);
}

// Floats as uints of the same order.
uint ordered_bits(float x) {
    uint b = floatBitsToUint(x);
    return (b & 0x80000000u) != 0u ? ~b : b | 0x80000000u;
}

// The extreme key: larger DIST wins, then the lower index. 0 is no key (no finite float
// orders to 0).
uint64_t extreme_key(float dist, uint i) {
    return (uint64_t(ordered_bits(dist)) << 32) | uint64_t(~i);
}

uint key_point(uint64_t key) {
    return key == 0ul ? HPR_EMPTY : ~uint(key & 0xfffffffful);
}

// The EMPTY cell of sector (i, j).
uint empty_cell(uint i, uint j) {
    return (i / h.coarse) * h.coarse_side + j / h.coarse;
}

// The complete visible set's grids (src/hpr/prefilter.rs): level l has complete_side >> l
// sectors per angle over the sector frame's angles, stored after the finer levels.
uint complete_offset(uint level) {
    uint offset = 0u;
    for (uint l = 0u; l < level; ++l) {
        uint s = p.complete_side >> l;
        offset += s * s;
    }
    return offset;
}

// The finest complete grid's sector of `v` (relative to the eye, length `n` > 0).
uvec2 complete_cell(vec3 v, float n) {
    vec3 l = vec3(dot(h.axis_x.xyz, v), dot(h.axis_y.xyz, v), dot(h.axis_z.xyz, v));
    float phi = atan(l.y, l.x);
    float theta = acos(clamp(l.z / n, -1.0, 1.0));
    vec2 step = h.grid.zw * float(h.sqrt_k) / float(p.complete_side);
    float last = float(p.complete_side - 1u);
    return uvec2(clamp(floor((vec2(phi, theta) - h.grid.xy) / step), vec2(0.0), vec2(last)));
}

#endif

#version 460
// The cloud's bounding sphere by parallel reduction (003 4.1), once per cloud: the centroid
// C_e (per-workgroup partial sums, then one workgroup adds the partials) and the largest
// distance from it (a workgroup maximum, then an atomic maximum of the radius' bits).
#define HPR_WRITES_SPHERE
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(constant_id = HPR_SPEC_MODE) const uint MODE = HPR_SPHERE_SUM;

// xyz: a workgroup's sum of positions.
layout(std430, set = 0, binding = BINDING_HPR_PARTIALS) buffer Partials {
    vec4 partials[];
};

shared vec4 sums[HPR_GROUP];
shared float radii[HPR_GROUP];

// Points per thread of the sum and radius passes.
const uint ITEMS = 16;

void main() {
    uint t = gl_LocalInvocationID.x;
    uint n = p.point_count;
    if (MODE == HPR_SPHERE_CENTRE) {
        // One workgroup: `p.sqrt_k` carries the number of partials.
        vec4 s = vec4(0.0);
        for (uint k = t; k < p.sqrt_k; k += HPR_GROUP) {
            s += partials[k];
        }
        sums[t] = s;
        radii[t] = 0.0;
    } else {
        uint base = gl_WorkGroupID.x * HPR_GROUP * ITEMS + t;
        vec4 s = vec4(0.0);
        float r = 0.0;
        for (uint k = 0; k < ITEMS; k++) {
            uint i = base + k * HPR_GROUP;
            if (i < n) {
                vec3 q = stream_position(i);
                s += vec4(q, 1.0);
                if (MODE == HPR_SPHERE_RADIUS) {
                    r = max(r, distance(q, sphere_centre));
                }
            }
        }
        sums[t] = s;
        radii[t] = r;
    }
    barrier();
    for (uint stride = HPR_GROUP / 2; stride > 0; stride /= 2) {
        if (t < stride) {
            sums[t] += sums[t + stride];
            radii[t] = max(radii[t], radii[t + stride]);
        }
        barrier();
    }
    if (t != 0u) {
        return;
    }
    if (MODE == HPR_SPHERE_SUM) {
        partials[gl_WorkGroupID.x] = sums[0];
    } else if (MODE == HPR_SPHERE_CENTRE) {
        sphere_centre = sums[0].xyz / max(float(n), 1.0);
        sphere_radius_bits = 0u;
    } else {
        atomicMax(sphere_radius_bits, floatBitsToUint(radii[0]));
    }
}

// The per-pixel accumulators of the kernel interpolation (000 6.2), in three RGBA32F images:
// (sum of w n, sum of w), (sum of w depth, sum of w radius, front depth, front half range),
// (sum of w albedo, unused). The bindings are read-write in the interpolation passes and read
// by the resolve.
#ifndef SURFEL_PYRAMID_KERNEL_ACCUM_GLSL
#define SURFEL_PYRAMID_KERNEL_ACCUM_GLSL
#include "kernel.glsl"

layout(set = 0, binding = BINDING_KERNEL_ACCUM, rgba32f) uniform image2D accum_a;
layout(set = 0, binding = BINDING_KERNEL_ACCUM + 1, rgba32f) uniform image2D accum_b;
layout(set = 0, binding = BINDING_KERNEL_ACCUM + 2, rgba32f) uniform image2D accum_c;

struct Accum {
    vec3 n;
    float weight;
    float depth;
    float radius;
    float front_depth;
    float front_range;
    vec3 color;
};

Accum accum_empty() {
    return Accum(vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, vec3(0.0));
}

Accum accum_load(ivec2 px) {
    vec4 a = imageLoad(accum_a, px);
    vec4 b = imageLoad(accum_b, px);
    vec3 c = COLOR ? imageLoad(accum_c, px).rgb : vec3(0.0);
    return Accum(a.xyz, a.w, b.x, b.y, b.z, b.w, c);
}

void accum_store(ivec2 px, Accum s) {
    imageStore(accum_a, px, vec4(s.n, s.weight));
    imageStore(accum_b, px, vec4(s.depth, s.radius, s.front_depth, s.front_range));
    if (COLOR) {
        imageStore(accum_c, px, vec4(s.color, 0.0));
    }
}

// Adds texel `t` with weight `w` under ch. 4's occlusion test, in the order of the search: a
// texel whose depth interval overlaps the front contribution's joins the sums, one behind it
// is discarded, one in front starts the sums anew.
void accum_add(inout Accum s, Texel t, float w) {
    if (s.weight > 0.0) {
        bool overlap = abs(t.depth - s.front_depth) <= t.half_range + s.front_range;
        if (!overlap && t.depth > s.front_depth) {
            return;
        }
        if (!overlap) {
            s = accum_empty();
        }
    }
    if (s.weight == 0.0) {
        s.front_depth = t.depth;
        s.front_range = t.half_range;
    }
    s.n += w * t.n;
    s.weight += w;
    s.depth += w * t.depth;
    s.radius += w * t.radius;
    s.color += w * t.color.rgb;
}
#endif

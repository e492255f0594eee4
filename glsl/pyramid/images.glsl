// The storage images of the pyramid passes: the groups of a parent level, of the level a pass
// reads, and of the level it writes (each A, B, C at three consecutive bindings).
#ifndef SURFEL_PYRAMID_IMAGES_GLSL
#define SURFEL_PYRAMID_IMAGES_GLSL
#include "pyramid.glsl"

layout(set = 0, binding = BINDING_PYRAMID_PARENT, rgba16f) uniform readonly image2D parent_a;
layout(set = 0, binding = BINDING_PYRAMID_PARENT + 1, rgba32f) uniform readonly image2D parent_b;
layout(set = 0, binding = BINDING_PYRAMID_PARENT + 2, rgba16f) uniform readonly image2D parent_c;
layout(set = 0, binding = BINDING_PYRAMID_LEVEL, rgba16f) uniform readonly image2D level_a;
layout(set = 0, binding = BINDING_PYRAMID_LEVEL + 1, rgba32f) uniform readonly image2D level_b;
layout(set = 0, binding = BINDING_PYRAMID_LEVEL + 2, rgba16f) uniform readonly image2D level_c;
layout(set = 0, binding = BINDING_PYRAMID_OUT, rgba16f) uniform writeonly image2D out_a;
layout(set = 0, binding = BINDING_PYRAMID_OUT + 1, rgba32f) uniform writeonly image2D out_b;
layout(set = 0, binding = BINDING_PYRAMID_OUT + 2, rgba16f) uniform writeonly image2D out_c;

Texel unpack_texel(vec4 a, vec4 b, vec4 c) {
    return Texel(a.xyz, a.w, b.x, b.y, b.zw, c);
}

Texel load_parent(ivec2 q) {
    return unpack_texel(imageLoad(parent_a, q), imageLoad(parent_b, q),
                        COLOR ? imageLoad(parent_c, q) : vec4(0.0));
}

Texel load_level(ivec2 q) {
    return unpack_texel(imageLoad(level_a, q), imageLoad(level_b, q),
                        COLOR ? imageLoad(level_c, q) : vec4(0.0));
}

void store_out(ivec2 q, Texel t) {
    imageStore(out_a, q, vec4(t.n, t.radius));
    imageStore(out_b, q, vec4(t.depth, t.half_range, t.disp));
    if (COLOR) {
        imageStore(out_c, q, t.color);
    }
}
#endif

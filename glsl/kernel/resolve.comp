#version 460
// Resolves the kernel interpolation (000 6.2) into level 0 of the pyramid for shade.comp:
// weighted means of the accumulated normal, depth, radius and albedo, the front
// contribution's half range, no displacement, a point's primitive id; empty where nothing
// contributed. Normals that cancel out fall back to one facing the camera.
#include "kernel_accum.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    Accum s = accum_load(px);
    if (s.weight == 0.0) {
        store_out(px, empty_texel());
        return;
    }
    float len = length(s.n);
    Texel t;
    t.n = len > 0.0 ? s.n / len : vec3(0.0, 0.0, 1.0);
    t.radius = s.radius / s.weight;
    t.depth = s.depth / s.weight;
    t.half_range = s.front_range;
    t.disp = vec2(0.0);
    t.color = vec4(s.color / s.weight, float(PRIMITIVE_POINT));
    store_out(px, t);
}

#version 460
// Deferred per-pixel Phong (000 4.2.3) on the reconstructed level 0 (or, to inspect the
// pyramid, on any level shown at full size): the interpolated normal and albedo are lit at the
// pixel's position on its ray at the interpolated depth, into the standard targets.
#include "images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;
layout(set = 0, binding = BINDING_OUTPUT0 + 1, r32f) uniform writeonly image2D out_depth;
layout(set = 0, binding = BINDING_OUTPUT0 + 2, rgba16f) uniform writeonly image2D out_normal;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    // `pyr.level`: the level shown (0 for the reconstruction), its texels magnified.
    ivec2 q = min(px >> pyr.level, imageSize(level_a) - 1);
    Texel t = load_level(q);
    if (t.depth <= 0.0) {
        imageStore(out_color, px, vec4(0.0));
        imageStore(out_depth, px, vec4(0.0));
        imageStore(out_normal, px, vec4(0.0));
        return;
    }
    vec2 ndc = (vec2(px) + 0.5) * frame.u.viewport.zw * 2.0 - 1.0;
    vec3 view_pos = vec3(ndc.x * t.depth / frame.u.proj[0][0],
                         ndc.y * t.depth / frame.u.proj[1][1], -t.depth);
    vec3 albedo = COLOR ? t.color.rgb : frame.u.base_color.rgb;
    vec3 n = normalize(t.n);
    bool tube = COLOR && uint(t.color.a) == PRIMITIVE_TUBE;
    vec3 lit = tube ? shade_tube(albedo, n, view_pos) : shade(albedo, n, view_pos);
    // A tube's normal target shows its camera-facing disc.
    n = tube ? vec3(0.0, 0.0, 1.0) : n;
    imageStore(out_color, px, vec4(linear_to_srgb(lit), 1.0));
    imageStore(out_depth, px, vec4(t.depth));
    imageStore(out_normal, px, vec4(n, 1.0));
}

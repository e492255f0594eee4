#version 460
// Resolves the s x s supersampled ground truth: color averaged in linear space over all samples
// (background black, so silhouettes are anti-aliased) then sRGB-encoded; a pixel is covered when
// at least half of its samples are; depth and normal are averaged over the covered samples.
#include "common.glsl"

layout(local_size_x = RESOLVE_GROUP, local_size_y = RESOLVE_GROUP) in;

layout(set = 0, binding = BINDING_INPUT0, rgba16f) uniform readonly image2D hi_color;
layout(set = 0, binding = BINDING_INPUT1, r32f) uniform readonly image2D hi_depth;
layout(set = 0, binding = BINDING_INPUT2, rgba16f) uniform readonly image2D hi_normal;
layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;
layout(set = 0, binding = BINDING_OUTPUT0 + 1, r32f) uniform writeonly image2D out_depth;
layout(set = 0, binding = BINDING_OUTPUT0 + 2, rgba16f) uniform writeonly image2D out_normal;

layout(push_constant) uniform Push { uint samples; } pc;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(px, imageSize(out_color)))) {
        return;
    }
    int s = int(pc.samples);
    vec3 color = vec3(0.0);
    vec3 normal = vec3(0.0);
    float depth = 0.0;
    int covered = 0;
    for (int y = 0; y < s; ++y) {
        for (int x = 0; x < s; ++x) {
            ivec2 q = px * s + ivec2(x, y);
            float d = imageLoad(hi_depth, q).r;
            if (d > 0.0) {
                covered += 1;
                color += imageLoad(hi_color, q).rgb;
                normal += imageLoad(hi_normal, q).xyz;
                depth += d;
            }
        }
    }
    bool is_covered = 2 * covered >= s * s;
    vec3 rgb = linear_to_srgb(color / float(s * s));
    imageStore(out_color, px, vec4(rgb, is_covered ? 1.0 : 0.0));
    imageStore(out_depth, px, vec4(is_covered ? depth / float(covered) : 0.0));
    float len = length(normal);
    imageStore(out_normal, px, is_covered && len > 0.0 ? vec4(normal / len, 1.0) : vec4(0.0));
}

#version 460
// Normalization pass (002 sections 5.3.2-5.3.4): divides the accumulated sums by the summed
// weight (eq. 5.6). Deferred shading lights here, once per pixel, with the averaged albedo and
// normal at the visible point, reconstructed from the visibility pass's linear depth and the
// pixel's ray (the paper keeps q in a separate target; the depth and ray give the same point).
#include "splat.glsl"

layout(local_size_x = RESOLVE_GROUP, local_size_y = RESOLVE_GROUP) in;

layout(set = 0, binding = BINDING_INPUT0, rgba16f) uniform readonly image2D accum_color;
layout(set = 0, binding = BINDING_INPUT1, rgba16f) uniform readonly image2D accum_normal;
layout(set = 0, binding = BINDING_INPUT2, r32f) uniform readonly image2D depth;
layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;
layout(set = 0, binding = BINDING_OUTPUT0 + 1, rgba16f) uniform writeonly image2D out_normal;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(px, imageSize(out_color)))) {
        return;
    }
    vec4 c = imageLoad(accum_color, px);
    vec4 n = imageLoad(accum_normal, px);
    if (c.a <= 0.0) {
        imageStore(out_color, px, vec4(0.0));
        imageStore(out_normal, px, vec4(0.0));
        return;
    }
    vec3 color = c.rgb / c.a;
    vec3 normal = n.xyz / max(length(n.xyz), 1e-20);
    if (SHADING == SPLAT_SHADING_DEFERRED) {
        vec3 q = pixel_ray(vec2(px) + 0.5) * imageLoad(depth, px).r;
        color = shade(color, normal, q);
    }
    imageStore(out_color, px, vec4(linear_to_srgb(color), 1.0));
    imageStore(out_normal, px, vec4(normal, 1.0));
}

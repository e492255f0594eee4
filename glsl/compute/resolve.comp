#version 460
// Resolves the compute rasterizer into the standard targets. Visibility: the winning point's
// position, normal and color are fetched (only for winners) and shaded like `points`.
// High quality: the accumulated albedo and normal are averaged and shaded at the nearest depth.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "streams.glsl"

layout(local_size_x = RESOLVE_GROUP, local_size_y = RESOLVE_GROUP) in;

layout(constant_id = RESOLVE_SPEC_HIGH_QUALITY) const bool HIGH_QUALITY = false;

layout(std430, set = 0, binding = BINDING_VISIBILITY) readonly buffer Visibility {
    uint64_t keys[];
};
layout(std430, set = 0, binding = BINDING_ACCUM) readonly buffer Accum { uint accum[]; };
layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;
layout(set = 0, binding = BINDING_OUTPUT0 + 1, r32f) uniform writeonly image2D out_depth;
layout(set = 0, binding = BINDING_OUTPUT0 + 2, rgba16f) uniform writeonly image2D out_normal;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    uint pixel = uint(px.y) * uint(size.x) + uint(px.x);
    uint64_t key = keys[pixel];
    if (key == ~0ul) {
        imageStore(out_color, px, vec4(0.0));
        imageStore(out_depth, px, vec4(0.0));
        imageStore(out_normal, px, vec4(0.0));
        return;
    }
    vec3 n;
    vec3 albedo;
    vec3 view_pos;
    if (HIGH_QUALITY) {
        uint a = 8u * pixel;
        float count = float(max(accum[a + 3u], 1u));
        albedo = vec3(accum[a], accum[a + 1u], accum[a + 2u]) / (255.0 * count);
        vec3 sum = vec3(ivec3(accum[a + 4u], accum[a + 5u], accum[a + 6u]));
        n = length(sum) > 0.0 ? normalize(sum) : vec3(0.0, 0.0, 1.0);
        float depth = uintBitsToFloat(uint(key >> 32));
        vec2 ndc = (vec2(px) + 0.5) * frame.u.viewport.zw * 2.0 - 1.0;
        view_pos = vec3(ndc.x * depth / frame.u.proj[0][0], ndc.y * depth / frame.u.proj[1][1],
                        -depth);
    } else {
        uint i = uint(key & 0xffffffffu);
        view_pos = (frame.u.view * vec4(stream_position(i), 1.0)).xyz;
        n = normalize(mat3(frame.u.view) * stream_normal(i));
        albedo = stream_albedo(i);
    }
    imageStore(out_color, px, vec4(linear_to_srgb(shade(albedo, n, view_pos)), 1.0));
    imageStore(out_depth, px, vec4(-view_pos.z));
    imageStore(out_normal, px, vec4(n, 1.0));
}

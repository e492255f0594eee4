// Shared helpers: the frame block, normal decoding, sRGB encoding and Phong lighting.
#ifndef SURFEL_COMMON_GLSL
#define SURFEL_COMMON_GLSL
#include "shared.glsl"

layout(std430, set = 0, binding = BINDING_FRAME) readonly buffer FrameBlock {
    FrameUniforms u;
    GpuLight lights[MAX_LIGHTS];
} frame;

// Octahedral normal decoding (two snorm16 in one uint).
vec3 oct_decode(uint packed) {
    vec2 e = unpackSnorm2x16(packed);
    vec3 n = vec3(e.x, e.y, 1.0 - abs(e.x) - abs(e.y));
    if (n.z < 0.0) {
        n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    }
    float len = length(n);
    return len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
}

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

// Two-sided Blinn-Phong in view space with every light of the frame.
vec3 shade(vec3 albedo, vec3 n, vec3 view_pos) {
    vec3 v = normalize(-view_pos);
    if (dot(n, v) < 0.0) {
        n = -n;
    }
    vec3 lit = albedo * frame.u.params.z;
    for (uint i = 0u; i < frame.u.light_count; ++i) {
        vec3 l = normalize(frame.lights[i].position.xyz - view_pos);
        vec3 h = normalize(l + v);
        vec3 c = frame.lights[i].color_kind.rgb;
        float diffuse = max(dot(n, l), 0.0);
        float specular = diffuse > 0.0 ? pow(max(dot(n, h), 0.0), frame.u.params.w) : 0.0;
        lit += c * (albedo * diffuse + 0.2 * specular);
    }
    return lit;
}
#endif

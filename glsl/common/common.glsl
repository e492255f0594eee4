// Shared helpers: the frame block, normal decoding, sRGB encoding, the color ramps and Phong
// lighting.
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

// An orthonormal tangent frame (t_u, t_v) of the plane with unit normal n: t_u = n x h with the
// helper axis h = +x unless |n.x| >= 0.9, then +y; t_v = n x t_u (mirrors `tangent_frame` in
// src/scene/normal_field.rs).
mat2x3 tangent_frame(vec3 n) {
    vec3 helper = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    vec3 tu = normalize(cross(n, helper));
    return mat2x3(tu, cross(n, tu));
}

// Whether the viewer's clipping box keeps local position p (src/scene/clip.rs).
bool clip_kept(vec3 p) {
    uint flags = frame.u.flags;
    if ((flags & FLAG_CLIP) == 0u) {
        return true;
    }
    vec3 b = (frame.u.clip * vec4(p, 1.0)).xyz;
    bool inside = max(max(abs(b.x), abs(b.y)), abs(b.z)) <= 1.0;
    return inside != ((flags & FLAG_CLIP_OUTSIDE) != 0u);
}

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

// An sRGB 0xRRGGBB constant in linear space.
vec3 rgb8(uint c) {
    return srgb_to_linear(vec3((c >> 16) & 255u, (c >> 8) & 255u, c & 255u) / 255.0);
}

// The scalar ramp at t in [0, 1] (clamped; NaN gives the start), interpolated in sRGB.
vec3 ramp(float t) {
    const uint stops[5] = uint[](RAMP_0, RAMP_1, RAMP_2, RAMP_3, RAMP_4);
    float x = isnan(t) ? 0.0 : clamp(t, 0.0, 1.0) * 4.0;
    uint k = min(uint(x), 3u);
    vec3 a = vec3((stops[k] >> 16) & 255u, (stops[k] >> 8) & 255u, stops[k] & 255u);
    uint e = stops[k + 1u];
    vec3 b = vec3((e >> 16) & 255u, (e >> 8) & 255u, e & 255u);
    return srgb_to_linear(mix(a, b, x - float(k)) / 255.0);
}

// Position of `value` in the frame's color range (0 at its start, 1 at its end).
float ramp_position(float value) {
    return (value - frame.u.color_range.x) * frame.u.color_range.y;
}

// The elevation ramp's albedo at local position p (COLOR_ELEVATION).
vec3 elevation_albedo(vec3 p) {
    return ramp(ramp_position(dot(p, frame.u.color_axis.xyz)));
}

// The unit normal n as an sRGB color (COLOR_NORMAL).
vec3 normal_albedo(vec3 n) {
    return srgb_to_linear(n * 0.5 + 0.5);
}

// The albedo of a sample standing for several points (a level of detail's vertex) with its
// points' mean color `rgba8`, its position p and unit normal n, under the frame's color mode as
// `stream_albedo` (glsl/common/streams.glsl) colors a point: the modes reading a scalar stream,
// which a sample does not keep, show the base color.
vec3 sample_albedo(uint rgba8, vec3 p, vec3 n) {
    uint mode = frame.u.color_mode;
    if (mode == COLOR_RGB) {
        return srgb_to_linear(unpackUnorm4x8(rgba8).rgb);
    }
    if (mode == COLOR_ELEVATION) {
        return elevation_albedo(p);
    }
    if (mode == COLOR_NORMAL) {
        return normal_albedo(n);
    }
    return frame.u.base_color.rgb;
}

// Blinn-Phong term of light `i` at `view_pos` for the unit normal `n`, seen along `v`.
vec3 light_term(uint i, vec3 albedo, vec3 n, vec3 v, vec3 view_pos) {
    float specular = frame.u.specular;
    float diffuse_weight = 1.0 - frame.u.ambient - specular;
    vec3 l = normalize(frame.lights[i].position.xyz - view_pos);
    vec3 h = normalize(l + v);
    vec3 c = frame.lights[i].color_kind.rgb;
    float diffuse = max(dot(n, l), 0.0);
    float highlight = diffuse > 0.0 ? pow(max(dot(n, h), 0.0), frame.u.specular_exponent) : 0.0;
    return c * albedo * (diffuse_weight * diffuse + specular * highlight);
}

// Two-sided Blinn-Phong in view space with every light of the frame. The weights keep the
// albedo: ambient + diffuse + specular = 1 at normal incidence under a unit light, and the
// specular is tinted by the albedo, so black stays black and a surface facing a headlight shows
// its own color. Attribute colors (FLAG_UNLIT) are returned as they are.
vec3 shade(vec3 albedo, vec3 n, vec3 view_pos) {
    if ((frame.u.flags & FLAG_UNLIT) != 0u) {
        return albedo;
    }
    vec3 v = normalize(-view_pos);
    if (dot(n, v) < 0.0) {
        n = -n;
    }
    vec3 lit = albedo * frame.u.ambient;
    for (uint i = 0u; i < frame.u.light_count; ++i) {
        lit += light_term(i, albedo, n, v, view_pos);
    }
    return lit;
}

// A thin tube with unit tangent `t` (000 5.1.2, line lighting): for each light the normal is
// the light vector projected on the plane perpendicular to the tangent.
vec3 shade_tube(vec3 albedo, vec3 t, vec3 view_pos) {
    if ((frame.u.flags & FLAG_UNLIT) != 0u) {
        return albedo;
    }
    vec3 v = normalize(-view_pos);
    vec3 lit = albedo * frame.u.ambient;
    for (uint i = 0u; i < frame.u.light_count; ++i) {
        vec3 l = normalize(frame.lights[i].position.xyz - view_pos);
        vec3 across = l - t * dot(t, l);
        float len = length(across);
        // A light along the tangent grazes the tube: light it as seen from the viewer.
        vec3 n = len > 1e-4 ? across / len : v;
        lit += light_term(i, albedo, n, v, view_pos);
    }
    return lit;
}
#endif

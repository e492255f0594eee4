#version 460
// A fixed-size point as a screen-aligned paraboloid (Potree's paraboloid point shape): the
// disc of the point's size, its depth d - r (1 - |u|²) at offset u from the centre in units of
// the radius r (the point's half size in view units at its depth), written to the hardware
// depth so that overlapping points intersect per pixel.
#include "common.glsl"

layout(location = 0) in vec3 v_albedo;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec3 v_view_pos;

layout(location = TARGET_COLOR) out vec4 o_color;
layout(location = TARGET_DEPTH) out float o_depth;
layout(location = TARGET_NORMAL) out vec4 o_normal;

void main() {
    vec2 u = gl_PointCoord * 2.0 - 1.0;
    float u2 = dot(u, u);
    if (u2 > 1.0) {
        discard;
    }
    float d = -v_view_pos.z;
    // One pixel spans 2 d / (|proj[1][1]| height) view units at depth d (the projection flips y).
    float radius = frame.u.point_size * d / (abs(frame.u.proj[1][1]) * frame.u.viewport.y);
    float depth = d - radius * (1.0 - u2);
    vec4 clip = frame.u.proj * vec4(v_view_pos.xy, -depth, 1.0);
    gl_FragDepth = clip.z / clip.w;
    vec3 n = normalize(v_normal);
    o_color = vec4(linear_to_srgb(shade(v_albedo, n, v_view_pos)), 1.0);
    o_depth = depth;
    o_normal = vec4(n, 1.0);
}

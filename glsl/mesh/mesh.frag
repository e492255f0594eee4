#version 460
// Ground truth shading at the supersampled resolution: linear color, linear depth, normal.
#include "common.glsl"

layout(location = 0) in vec3 v_albedo;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec3 v_view_pos;

layout(location = TARGET_COLOR) out vec4 o_color;
layout(location = TARGET_DEPTH) out float o_depth;
layout(location = TARGET_NORMAL) out vec4 o_normal;

void main() {
    vec3 n = normalize(v_normal);
    vec3 v = normalize(-v_view_pos);
    if (dot(n, v) < 0.0) {
        n = -n;
    }
    o_color = vec4(shade(v_albedo, n, v_view_pos), 1.0);
    o_depth = -v_view_pos.z;
    o_normal = vec4(n, 1.0);
}

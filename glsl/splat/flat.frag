#version 460
// Flat shading (002 section 5.3.1), one pass: every covered fragment takes its splat's color
// (lit once per splat in the vertex stage), nearest surface point wins.
#include "fragment.glsl"

layout(location = TARGET_COLOR) out vec4 o_color;
layout(location = TARGET_DEPTH) out float o_depth;
layout(location = TARGET_NORMAL) out vec4 o_normal;

void main() {
    SplatHit hit = splat_fragment();
    gl_FragDepth = zbuffer_depth(hit.q);
    o_color = vec4(linear_to_srgb(v_color), 1.0);
    o_depth = -hit.q.z;
    o_normal = vec4(v_normal, 1.0);
}

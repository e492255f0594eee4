#version 460
// Ground truth: the input triangle mesh, vertices pulled from the point streams by index.
#include "streams.glsl"

layout(location = 0) out vec3 v_albedo;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec3 v_view_pos;

void main() {
    uint i = uint(gl_VertexIndex);
    vec4 view_pos = frame.u.view * vec4(stream_position(i), 1.0);
    gl_Position = frame.u.proj * view_pos;
    v_albedo = stream_albedo(i);
    v_normal = mat3(frame.u.view) * stream_normal(i);
    v_view_pos = view_pos.xyz;
}

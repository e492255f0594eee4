#version 460
// Fixed-size points (002 §5.2 method 1): one vertex per point, pulled from the point streams.
#include "streams.glsl"
#include "live.glsl"

layout(location = 0) out vec3 v_albedo;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec3 v_view_pos;

void main() {
    uint i = uint(gl_VertexIndex);
    vec3 local = stream_position(i);
    vec4 view_pos = frame.u.view * vec4(local, 1.0);
    gl_Position = frame.u.proj * view_pos;
    if (!stream_live(i) || !point_kept(i, local)) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    }
    gl_PointSize = frame.u.point_size;
    v_albedo = stream_albedo(i);
    v_normal = mat3(frame.u.view) * stream_normal(i);
    v_view_pos = view_pos.xyz;
}

#version 460
// Ground truth: the input triangle mesh, vertices pulled from the point buffer by index.
#include "common.glsl"

layout(std430, set = 0, binding = BINDING_POINTS) readonly buffer Points { GpuPoint points[]; };

layout(location = 0) out vec3 v_albedo;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec3 v_view_pos;

void main() {
    GpuPoint p = points[gl_VertexIndex];
    vec4 view_pos = frame.u.view * vec4(point_position(p), 1.0);
    gl_Position = frame.u.proj * view_pos;
    v_albedo = point_albedo(p);
    v_normal = mat3(frame.u.view) * oct_decode(p.normal_oct);
    v_view_pos = view_pos.xyz;
}

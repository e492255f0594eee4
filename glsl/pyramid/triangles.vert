#version 460
// Triangles in the pyramid (000 5.2): mesh faces rasterized into level 0 with a radius of 0,
// so the pyramid never expands them; their vertices are pulled from the point streams by
// index. Two-sided: each vertex normal faces the camera. Written by project.frag.
#include "streams.glsl"
#include "pyramid.glsl"

layout(location = 0) out vec4 v_a;
layout(location = 1) out vec4 v_b;
layout(location = 2) out vec3 v_c;
layout(location = 3) flat out uint v_primitive;

void main() {
    uint i = uint(gl_VertexIndex);
    vec3 p = (frame.u.view * vec4(stream_position(i), 1.0)).xyz;
    vec3 n = normalize(mat3(frame.u.view) * stream_normal(i));
    gl_Position = frame.u.proj * vec4(p, 1.0);
    v_a = vec4(dot(n, p) > 0.0 ? -n : n, 0.0);
    v_b = vec4(-p.z, 0.0, 0.0, 0.0);
    v_c = COLOR ? stream_albedo(i) : vec3(0.0);
    v_primitive = PRIMITIVE_TRIANGLE;
}

#version 460
// Lines in the pyramid (000 5.1): ribbon or tube segments rasterized 1 pixel wide into level 0
// (written by project.frag), their vertices pulled from the point streams by index. A ribbon's
// vertex carries its normal and half width (no back-face culling: the normal turns to the
// camera, lit two-sided); a tube's its tangent and radius (interpolated as a view-facing disc,
// lit with the light vector projected across the tangent; shade.comp). The radii are geometry,
// not sampling density: the `radius` scale does not apply.
#include "streams.glsl"
#include "pyramid.glsl"

layout(constant_id = PYRAMID_SPEC_TUBE) const bool TUBE = false;

layout(location = 0) out vec4 v_a;
layout(location = 1) out vec4 v_b;
layout(location = 2) out vec3 v_c;
layout(location = 3) flat out uint v_primitive;

void main() {
    uint i = uint(gl_VertexIndex);
    vec3 p = (frame.u.view * vec4(stream_position(i), 1.0)).xyz;
    vec3 d = normalize(mat3(frame.u.view) * stream_normal(i));
    gl_Position = frame.u.proj * vec4(p, 1.0);
    float r = stream_radius(i);
    float depth = -p.z;
    if (!TUBE && dot(d, p) > 0.0) {
        d = -d;
    }
    v_a = vec4(d, r * 0.5 * frame.u.viewport.y * abs(frame.u.proj[1][1]) / depth);
    v_b = vec4(depth, r, 0.0, 0.0);
    v_c = COLOR ? stream_albedo(i) : vec3(0.0);
    v_primitive = TUBE ? PRIMITIVE_TUBE : PRIMITIVE_RIBBON;
}

#version 460
// Level 0 of the pyramid from the level of detail's selection (000 ch. 7, the thesis' system):
// the object-texture vertices the selection chose (lod/select.comp), pulled through its list
// by an indirect draw and projected to one pixel each as project.vert projects points, with
// their own radius (a coarser level's splat covers its points), normal and albedo
// (`sample_albedo`: the mean color, elevation or normal; scalar modes read per-point streams
// the object texture does not keep, and show the base color). Back-facing samples are culled
// by normal (`CULL`).
#include "pyramid.glsl"

layout(constant_id = PYRAMID_SPEC_CULL) const bool CULL = true;

layout(std430, set = 0, binding = BINDING_LOD_VERTICES) readonly buffer Vertices {
    GpuLodVertex vertices[];
};
layout(std430, set = 0, binding = BINDING_LOD_LIST) readonly buffer List { uint list[]; };

layout(location = 0) out vec4 v_a;
layout(location = 1) out vec4 v_b;
layout(location = 2) out vec3 v_c;
layout(location = 3) flat out uint v_primitive;

void main() {
    GpuLodVertex v = vertices[list[gl_VertexIndex]];
    vec3 p = (frame.u.view * vec4(v.sphere.xyz, 1.0)).xyz;
    vec3 n = normalize(mat3(frame.u.view) * oct_decode(v.normal_color.x));
    gl_Position = frame.u.proj * vec4(p, 1.0);
    gl_PointSize = 1.0;
    if (dot(n, p) > 0.0) {
        if (CULL) {
            gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        }
        n = -n;
    }
    // The input points' radii are scaled as the pyramid scales points (`radius`); a coarser
    // splat's radius already bounds its points' discs and is kept (scaled too, the
    // representatives of a framed sphere at epsilon 64 cover 15 % more pixels than its points).
    float r = v.sphere.w * (v.normal_color.z == 0u ? pyr.radius_scale : 1.0);
    float depth = -p.z;
    v_a = vec4(n, r * 0.5 * frame.u.viewport.y * abs(frame.u.proj[1][1]) / depth);
    v_b = vec4(depth, r, 0.0, 0.0);
    vec3 albedo = sample_albedo(v.normal_color.y, v.sphere.xyz, oct_decode(v.normal_color.x));
    v_c = COLOR ? albedo : vec3(0.0);
    v_primitive = PRIMITIVE_POINT;
}

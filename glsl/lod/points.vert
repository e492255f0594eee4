#version 460
// The compute expansion's draw (000 7.2): the object-texture vertices the selection chose,
// pulled through its list.
#include "lod.glsl"

layout(constant_id = LOD_SPEC_COLOR_LEVELS) const bool COLOR_LEVELS = false;

layout(std430, set = 0, binding = BINDING_LOD_VERTICES) readonly buffer Vertices {
    GpuLodVertex vertices[];
};
layout(std430, set = 0, binding = BINDING_LOD_LIST) readonly buffer List { uint list[]; };

layout(push_constant) uniform Push { LodParams pc; };

layout(location = 0) flat out vec3 v_color;
layout(location = 1) flat out vec3 v_normal;
layout(location = 2) flat out vec3 v_centre;
layout(location = 3) flat out float v_radius;
layout(location = 4) flat out float v_size;

void main() {
    LodSplat o = lod_splat(vertices[list[gl_VertexIndex]], pc.max_point_size, COLOR_LEVELS);
    gl_Position = o.position;
    gl_PointSize = o.size;
    v_color = o.color;
    v_normal = o.normal;
    v_centre = o.centre;
    v_radius = o.radius;
    v_size = o.size;
}

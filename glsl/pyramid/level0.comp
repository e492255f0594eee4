#version 460
// Level 0 of the pyramid from the compute projection (000 4.2.1): each pixel's nearest point
// (the 64-bit visibility key; back-facing points were culled there) becomes a texel: its
// view-space normal and projected radius, linear depth, depth-interval half range (the splat
// radius), no displacement, and its albedo. Attributes are fetched for winners only.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "streams.glsl"
#include "images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

// Hybrid scenes (000 5.2): level 0 already holds the rasterized triangles (bound as the level
// read, the same image level as the output); the point wins only where it is nearer by more
// than its depth interval (its radius). Deviation: a point on the triangles' surface (a mesh's
// vertex no face references) would otherwise win about half its pixels and spread its ellipse
// over the exact triangles (docs/claims.md).
layout(constant_id = PYRAMID_SPEC_HYBRID) const bool HYBRID = false;

layout(std430, set = 0, binding = BINDING_VISIBILITY) readonly buffer Visibility {
    uint64_t keys[];
};

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    uint64_t key = keys[uint(px.y) * uint(size.x) + uint(px.x)];
    Texel triangle = HYBRID ? load_level(px) : empty_texel();
    if (key == ~0ul) {
        store_out(px, triangle);
        return;
    }
    uint i = uint(key & 0xffffffffu);
    vec3 p = (frame.u.view * vec4(stream_position(i), 1.0)).xyz;
    vec3 n = normalize(mat3(frame.u.view) * stream_normal(i));
    // Two-sided: the normal faces the camera.
    n = dot(n, p) > 0.0 ? -n : n;
    float r = stream_radius(i) * pyr.radius_scale;
    float depth = -p.z;
    if (triangle.depth > 0.0 && triangle.depth <= depth + r) {
        store_out(px, triangle);
        return;
    }
    Texel t;
    t.n = n;
    t.radius = r * 0.5 * frame.u.viewport.y * abs(frame.u.proj[1][1]) / depth;
    t.depth = depth;
    t.half_range = r;
    t.disp = vec2(0.0);
    t.color = vec4(COLOR ? stream_albedo(i) : vec3(0.0), float(PRIMITIVE_POINT));
    store_out(px, t);
}

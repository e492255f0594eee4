#version 460
// Level 0 of the pyramid through the hardware point pipeline (000 4.2.1, the thesis' own
// path): one 1-pixel point per point, nearest depth wins by the depth test, back-facing
// points culled by their normal (`CULL`), the texel written through three render targets
// (project.frag). In hybrid scenes the triangles were drawn first into the same targets, and
// a point is depth-tested its radius further away: it wins over a triangle only where it is
// nearer by more than its depth interval (as level0.comp decides).
#include "streams.glsl"
#include "pyramid.glsl"
#include "live.glsl"

layout(constant_id = PYRAMID_SPEC_CULL) const bool CULL = true;

layout(constant_id = PYRAMID_SPEC_HYBRID) const bool HYBRID = false;

layout(std430, set = 0, binding = BINDING_FACE_VERTICES) readonly buffer FaceVertices {
    uint face_vertex[];
};

layout(location = 0) out vec4 v_a;
layout(location = 1) out vec4 v_b;
layout(location = 2) out vec3 v_c;
layout(location = 3) flat out uint v_primitive;

void main() {
    uint i = uint(gl_VertexIndex);
    vec3 local = stream_position(i);
    vec3 p = (frame.u.view * vec4(local, 1.0)).xyz;
    vec3 n = normalize(mat3(frame.u.view) * stream_normal(i));
    float r = stream_radius(i) * pyr.radius_scale;
    float depth = -p.z;
    // Along its ray, the same pixel: only the depth tested moves (behind the eye the point is
    // clipped as it is).
    vec3 tested = HYBRID && depth > 0.0 ? p * ((depth + r) / depth) : p;
    gl_Position = frame.u.proj * vec4(tested, 1.0);
    gl_PointSize = 1.0;
    // Hybrid scenes: a face's vertex is drawn as part of its triangles, not as a point; an
    // empty index of a streamed pool or a point the viewer's filter hides is not drawn at all.
    if ((HYBRID && (face_vertex[i >> 5u] & (1u << (i & 31u))) != 0u) || !stream_live(i)
        || !point_kept(i, local)) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    }
    if (dot(n, p) > 0.0) {
        // Back-facing: moved outside the clip volume (discarded) when culling, else turned
        // to face the camera.
        if (CULL && (frame.u.flags & FLAG_HAS_NORMALS) != 0u) {
            gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        }
        n = -n;
    }
    v_a = vec4(n, r * 0.5 * frame.u.viewport.y * abs(frame.u.proj[1][1]) / depth);
    v_b = vec4(depth, r, 0.0, 0.0);
    v_c = COLOR ? stream_albedo(i) : vec3(0.0);
    v_primitive = PRIMITIVE_POINT;
}

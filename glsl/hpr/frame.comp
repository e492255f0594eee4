#version 460
// The per-frame sector frame (003 4.1), one thread: the eye from the view matrix; x towards
// the bounding sphere's centre C_e; the angular extent 2 asin(r / |C - C_e|), or the full
// sphere when the eye is inside or near the sphere; sqrt(k) from the viewport unless
// requested; R; the EMPTY grid's coarseness; cleared counters and indirect arguments.
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = 1) in;

const float PI = 3.14159265358979;

void main() {
    mat4 view = frame.u.view;
    vec3 eye = -(transpose(mat3(view)) * view[3].xyz);
    vec3 centre = sphere_centre;
    float r = uintBitsToFloat(sphere_radius_bits);
    vec3 to = centre - eye;
    float d = length(to);
    bool full = d <= r || asin(r / d) > PI / 3.0;
    vec3 x = d > 0.0 ? to / d : vec3(1.0, 0.0, 0.0);
    vec3 helper = abs(x.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
    vec3 y = normalize(cross(helper, x));
    vec3 z = cross(x, y);
    float half_phi = full ? PI : max(asin(r / d), 1e-9);
    float half_theta = full ? 0.5 * PI : half_phi;
    uint s;
    if (p.sqrt_k > 0u) {
        s = min(p.sqrt_k, p.sqrt_k_max);
    } else if (full) {
        s = p.sqrt_k_max;
    } else {
        // One sector per pixel across the sphere's projection (the pixel's angle at the
        // image centre).
        float pixel = 2.0 / (abs(frame.u.proj[1][1]) * frame.u.viewport.y);
        s = clamp(uint(ceil(2.0 * half_phi / pixel)), 1u, p.sqrt_k_max);
    }
    float far = d + r;
    float radius = p.radius > 0.0 ? p.radius : p.density * d * d;
    h.axis_x = vec4(x, 0.0);
    h.axis_y = vec4(y, 0.0);
    h.axis_z = vec4(z, 0.0);
    h.eye_radius = vec4(eye, max(radius, 1.01 * far));
    h.grid = vec4(-half_phi, 0.5 * PI - half_theta, 2.0 * half_phi / float(s),
        2.0 * half_theta / float(s));
    h.sqrt_k = s;
    h.full = full ? 1u : 0u;
    // The smallest c with c^2 n >= k: one EMPTY cell per sector unless sectors outnumber
    // points.
    uint k = s * s;
    uint coarse = 1u;
    while (uint64_t(coarse * coarse) * uint64_t(max(p.point_count, 1u)) < uint64_t(k)) {
        coarse++;
    }
    h.coarse = coarse;
    h.coarse_side = (s + coarse - 1u) / coarse;
    uint groups = (k + HPR_GROUP - 1u) / HPR_GROUP;
    h.groups_x = min(groups, MAX_GROUPS);
    h.groups_y = (groups + MAX_GROUPS - 1u) / MAX_GROUPS;
    h.groups_z = 1u;
    h.changed = 0u;
    h.rounds = 0u;
    h.visible = 0u;
    h.index_count = 0u;
    h.instance_count = 1u;
    h.first_index = 0u;
    h.vertex_offset = 0u;
    h.first_instance = 0u;
}

#version 460
// Splat setup (002 section 5.2): one point sprite per point, sized by the rasterization variant;
// flat and Gouraud shading light the splat here, once per splat (002 sections 5.3.1-5.3.2).
#include "streams.glsl"
#include "splat.glsl"
#include "live.glsl"

layout(location = 0) flat out vec3 v_color;
layout(location = 1) flat out vec3 v_normal;
layout(location = 2) flat out vec3 v_centre;
layout(location = 3) flat out float v_radius;
layout(location = 4) flat out float v_size;
layout(location = 5) flat out mat3 v_field;

void main() {
    uint i = uint(gl_VertexIndex);
    vec3 local = stream_position(i);
    vec3 p = (frame.u.view * vec4(local, 1.0)).xyz;
    vec3 n = normalize(mat3(frame.u.view) * stream_normal(i));
    float r = stream_radius(i) * splat.radius_scale;
    float d = -p.z;
    // Pixels per view-space unit at distance 1: h / 2 * |2n / (t - b)|.
    float k = 0.5 * frame.u.viewport.y * abs(frame.u.proj[1][1]);
    float size;
    if (RASTER == SPLAT_RASTER_POINTS) {
        size = frame.u.point_size;
    } else if (RASTER == SPLAT_RASTER_PERSPECTIVE) {
        // Deviation from eq. 5.1: the perspective projection of the disc is not centred on the
        // projection of p and its near side is magnified, so the sprite is sized to bound every
        // point within r of p: offset r (1 + |p_xy| / d) / (d - r) at the image plane.
        float spread = 1.0 + max(abs(p.x), abs(p.y)) / max(d, 1e-20);
        size = 2.0 * k * r * spread / max(d - r, frame.u.near);
    } else {
        // Eq. 5.1: 2 r * n / p_z * h / (t - b).
        size = 2.0 * k * r / max(d, 1e-20);
    }
    // Deviation: sprites are clamped to the device's point size range, so a splat larger than
    // max_point_size pixels is cut to that square (the tests and benchmarks stay far below).
    size = clamp(size, 1.0, splat.max_point_size);
    gl_Position = frame.u.proj * vec4(p, 1.0);
    // Back-face culling by normal (`cull`): a splat whose normal faces away from the eye is
    // moved outside the clip volume, which discards the point; so is a point the viewer's
    // filter hides.
    if ((CULL != 0u && dot(n, -p) < 0.0) || !stream_live(i) || !point_kept(i, local)) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    }
    gl_PointSize = size;
    vec3 albedo = stream_albedo(i);
    bool lit_here = SHADING == SPLAT_SHADING_FLAT || SHADING == SPLAT_SHADING_GOURAUD;
    v_color = lit_here ? shade(albedo, n, p) : albedo;
    v_normal = n;
    v_centre = p;
    v_radius = r;
    v_size = size;
    // Phong: the linear normal field, n(q) = n + v_field (q - p).
    v_field = SHADING == SPLAT_SHADING_PHONG ? stream_normal_field_view(i) : mat3(0.0);
}

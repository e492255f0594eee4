// The fragment side of the splatting family: which sprite fragments a splat covers, and where
// (002 section 5.2). Included by the flat, visibility and accumulation fragment shaders.
#ifndef SURFEL_SPLAT_FRAGMENT_GLSL
#define SURFEL_SPLAT_FRAGMENT_GLSL
#include "splat.glsl"

layout(location = 0) flat in vec3 v_color;
layout(location = 1) flat in vec3 v_normal;
layout(location = 2) flat in vec3 v_centre;
layout(location = 3) flat in float v_radius;
layout(location = 4) flat in float v_size;
// Phong shading's linear normal field: the normal at q is n + v_field (q - p), view space.
layout(location = 5) flat in mat3 v_field;

// A covered fragment: the view-space surface point q it shows and its normalized distance rho
// from the splat's centre (1 at the rim of the disc).
struct SplatHit {
    vec3 q;
    float rho;
};

// Evaluates the splat at this fragment. Discards fragments outside the splat.
SplatHit splat_fragment() {
    vec3 p = v_centre;
    vec3 n = v_normal;
    float r = v_radius;
    SplatHit hit;
    if (RASTER == SPLAT_RASTER_PERSPECTIVE) {
        // Eqs. 5.4-5.5: the ray through the pixel centre meets the splat plane at
        // q = q_n (p . n) / (q_n . n); discard when parallel, behind the eye or beyond r.
        vec3 qn = pixel_ray(gl_FragCoord.xy);
        float denom = dot(qn, n);
        if (abs(denom) < 1e-6 * length(qn)) {
            discard;
        }
        vec3 q = qn * (dot(p, n) / denom);
        float dist = length(q - p);
        if (q.z >= 0.0 || dist > r) {
            discard;
        }
        hit.q = q;
        hit.rho = dist / r;
        return hit;
    }
    // Offset of the fragment from the sprite centre in pixels (gl_PointCoord is in [0, 1] across
    // the sprite, y down like the framebuffer), then in view units in the plane z = p_z: the
    // projection's y scale is negative (Vulkan's y flip), so it also turns y up.
    vec2 px = (gl_PointCoord - 0.5) * v_size;
    float d = -p.z;
    vec2 xy = vec2(px.x * 2.0 * d * frame.u.viewport.z / frame.u.proj[0][0],
                   px.y * 2.0 * d * frame.u.viewport.w / frame.u.proj[1][1]);
    if (RASTER == SPLAT_RASTER_AFFINE) {
        // Eq. 5.2: the depth offset of the oriented disc under a parallel projection; the
        // fragment belongs to the splat when |(x, y, dz)| <= r. An edge-on disc covers nothing.
        if (abs(n.z) < 1e-4) {
            discard;
        }
        float dz = -(n.x / n.z) * xy.x - (n.y / n.z) * xy.y;
        float dist = length(vec3(xy, dz));
        if (dist > r) {
            discard;
        }
        hit.q = p + vec3(xy, dz);
        hit.rho = dist / r;
        return hit;
    }
    // Fixed-size points and image-aligned squares cover their whole square at the depth of p;
    // the weight falls off over the sprite's inscribed circle.
    hit.q = p + vec3(xy, 0.0);
    hit.rho = length(gl_PointCoord - 0.5) * 2.0;
    return hit;
}
#endif

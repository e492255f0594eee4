// The splatting family (002 sections 5.2-5.3): each point is drawn as one hardware point sprite
// and every fragment of the sprite is tested against the splat the rasterization variant
// describes. Variants are specialization constants, shared by every stage.
#ifndef SURFEL_SPLAT_GLSL
#define SURFEL_SPLAT_GLSL
#include "common.glsl"

layout(constant_id = SPLAT_SPEC_RASTER) const uint RASTER = SPLAT_RASTER_POINTS;
layout(constant_id = SPLAT_SPEC_SHADING) const uint SHADING = SPLAT_SHADING_FLAT;
layout(constant_id = SPLAT_SPEC_CULL) const uint CULL = 0u;

layout(push_constant) uniform Push {
    SplatParams splat;
};

// Per-splat values handed from the vertex to the fragment stage (all flat).
struct SplatVarying {
    // Flat and Gouraud: the splat's lit color; Phong and deferred: its albedo (linear).
    vec3 color;
    // View-space unit normal.
    vec3 normal;
    // View-space centre p.
    vec3 centre;
    // View-space radius r (scaled by `radius`).
    float radius;
    // Sprite size in pixels (after clamping to the device's range).
    float size;
};

// The splat's weight at normalized distance rho from its centre (1 at the rim): a Gaussian
// with sigma = r / 2, truncated at the rim of the disc (002 section 5.3.2 asks for a weight that
// falls off from the centre).
float splat_weight(float rho) {
    return exp(-2.0 * rho * rho);
}

// The reversed-Z depth-buffer value of view-space point q: the projection's z / w, which for this
// infinite reversed projection is near / -q.z (002 eq. 5.3 written for this frustum).
float zbuffer_depth(vec3 q) {
    vec4 clip = frame.u.proj * vec4(q, 1.0);
    return clamp(clip.z / clip.w, 0.0, 1.0);
}

// The direction of the ray from the eye through window position `frag` (pixels), scaled to
// view-space z = -1: the inverse of the viewport and projection transforms (002 eq. 5.4 with the
// near plane at distance 1).
vec3 pixel_ray(vec2 frag) {
    vec2 ndc = frag * 2.0 * frame.u.viewport.zw - 1.0;
    mat4 p = frame.u.proj;
    return vec3((ndc.x + p[2][0]) / p[0][0], (ndc.y + p[2][1]) / p[1][1], -1.0);
}
#endif

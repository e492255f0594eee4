// Level of detail from object textures (000 ch. 7, src/lod): the per-patch level choice every
// expansion path shares.
#ifndef SURFEL_LOD_GLSL
#define SURFEL_LOD_GLSL
#include "common.glsl"

// The eye in world space (the view matrix is rigid).
vec3 lod_eye() {
    return -(transpose(mat3(frame.u.view)) * frame.u.view[3].xyz);
}

// Pixels per unit of tan(angle) at distance 1: viewport height / (2 tan(fov_y / 2)).
float lod_focal() {
    return abs(frame.u.proj[1][1]) * frame.u.viewport.y * 0.5;
}

// The factor projecting a patch's perpendicular errors to pixels (000 7.1.2): sin(alpha) /
// |v| times the focal length, alpha the angle between the view vector v and the
// representative's normal (`ObjectTexture::projected_scale` is the CPU reference).
float lod_scale(GpuLodPatch rep) {
    vec3 v = rep.sphere.xyz - lod_eye();
    float dist = max(length(v), 1.17549435e-38);
    float c = clamp(dot(v, rep.normal.xyz) / dist, -1.0, 1.0);
    return sqrt(1.0 - c * c) / dist * lod_focal();
}

// The coarsest level whose projected perpendicular error e_p sin(alpha) / |v|, in pixels, is
// at most `limit` (000 7.1.2); `ObjectTexture::choose` is the CPU reference.
uint lod_level(GpuLodPatch rep, float limit) {
    float scale = lod_scale(rep);
    for (uint l = rep.levels - 1u; l > 0u; --l) {
        if (rep.errors[l] * scale <= limit) {
            return l;
        }
    }
    return 0u;
}

// The point budget's bin of a projected error `e` > 0 (see LOD_BUDGET_BINS).
uint lod_budget_bin(float e) {
    int b = int(floatBitsToUint(e) >> 20) - LOD_BUDGET_BIN_BASE;
    return uint(clamp(b, 0, LOD_BUDGET_BINS - 1));
}

// The members of the counters buffer every path binds at BINDING_LOD_COUNTERS (byte offsets
// in src/lod/gpu.rs): the list's VkDrawIndirectCommand, the samples emitted per level, the
// threshold the levels are chosen with, and the point budget's coarsest samples and bins.
#define LOD_COUNTERS_MEMBERS \
    uint draw[4]; \
    uint per_level[LOD_MAX_LEVELS]; \
    float threshold; \
    uint budget_base; \
    uint budget_pad[2]; \
    uint bins[LOD_BUDGET_BINS];

// Whether the patch's bounding sphere (the representative's disc covers its descendants')
// reaches into the view: inside the four side planes and in front of the eye's plane
// (`ObjectTexture::in_view` is the CPU reference). Culled patches emit nothing.
bool lod_in_view(GpuLodPatch rep) {
    mat4 m = frame.u.view_proj;
    vec4 x = vec4(m[0][0], m[1][0], m[2][0], m[3][0]);
    vec4 y = vec4(m[0][1], m[1][1], m[2][1], m[3][1]);
    vec4 w = vec4(m[0][3], m[1][3], m[2][3], m[3][3]);
    vec4 planes[5] = vec4[](w + x, w - x, w + y, w - y, w);
    vec4 c = vec4(rep.sphere.xyz, 1.0);
    for (int i = 0; i < 5; ++i) {
        if (dot(planes[i], c) < -rep.sphere.w * length(planes[i].xyz)) {
            return false;
        }
    }
    return true;
}

// First vertex of `level` in the object texture: the patch's levels are stored coarsest first.
uint lod_level_offset(GpuLodPatch rep, uint level) {
    uint first = rep.offset;
    for (uint l = rep.levels - 1u; l > level; --l) {
        first += rep.counts[l];
    }
    return first;
}
// A vertex's albedo (linear) under the frame's color mode (`sample_albedo`).
vec3 lod_albedo(GpuLodVertex v) {
    return sample_albedo(v.normal_color.y, v.sphere.xyz, oct_decode(v.normal_color.x));
}

// What every draw path emits for one object-texture vertex: a splat of the splatting family
// (002 5.2), shaded by splat/flat.frag under the same RASTER: an image-aligned square of the
// splat's projected diameter (eq. 5.1), or a perspective-correct disc (eqs. 5.4-5.5) in a
// sprite bounding it, at most `max_size` pixels either way; lit once per splat (flat
// shading), colored by level (thesis Fig. 7.4) or as `sample_albedo` colors it (the mean color
// of its points, its elevation or normal; the base color for scalar modes). The thesis projects the vertices
// into its pyramid renderer: that is `pyramid-lod` (pyramid/project_lod.vert).
layout(constant_id = SPLAT_SPEC_RASTER) const uint LOD_RASTER = SPLAT_RASTER_SQUARES;

struct LodSplat {
    vec4 position;
    float size;
    // Lit color (linear), view-space unit normal, centre and radius.
    vec3 color;
    vec3 normal;
    vec3 centre;
    float radius;
};

LodSplat lod_splat(GpuLodVertex v, float max_size, bool color_levels) {
    LodSplat o;
    vec3 p = (frame.u.view * vec4(v.sphere.xyz, 1.0)).xyz;
    o.position = frame.u.proj * vec4(p, 1.0);
    // The viewer's clipping box applies to the sample's centre (a sample stands for many
    // points: the class filter does not apply); outside the clip volume it is discarded.
    if (!clip_kept(v.sphere.xyz)) {
        o.position = vec4(2.0, 2.0, 2.0, 1.0);
    }
    float d = max(-p.z, 1e-6);
    float r = v.sphere.w;
    float size;
    if (LOD_RASTER == SPLAT_RASTER_PERSPECTIVE) {
        // As splat/splat.vert: the sprite bounds every point within r of p.
        float spread = 1.0 + max(abs(p.x), abs(p.y)) / d;
        size = 2.0 * lod_focal() * r * spread / max(d - r, frame.u.near);
    } else {
        size = 2.0 * r * lod_focal() / d;
    }
    o.size = clamp(size, 1.0, max_size);
    const uint colors[4] = uint[](LOD_COLOR_0, LOD_COLOR_1, LOD_COLOR_2, LOD_COLOR_3);
    uint c = colors[min(v.normal_color.z, 3u)];
    vec3 albedo = color_levels
        ? srgb_to_linear(vec3((c >> 16) & 255u, (c >> 8) & 255u, c & 255u) / 255.0)
        : lod_albedo(v);
    o.normal = normalize(mat3(frame.u.view) * oct_decode(v.normal_color.x));
    o.color = shade(albedo, o.normal, p);
    o.centre = p;
    o.radius = r;
    return o;
}
#endif

#version 460
// EWA surface splatting (Marroquim 2008, ch. 3), rasterized in compute. One workgroup per batch
// of Morton-ordered points; every thread sets up its splats and rasterizes each resampling
// ellipse's bounding box. A splat whose box reaches further than EWA_MAX_RADIUS pixels from its
// centre is left to the LARGE variant: the visibility pass appends it to the large splats'
// list, and one workgroup per listed splat shares its box among its threads (bounded work per
// thread; a box is at most the viewport).
//   MODE_VISIBILITY: every fragment's depth interval [front, back] goes through a 64-bit
//       atomicMin of (front bits << 32 | back bits): per pixel, the interval of the front-most
//       fragment, the surface the pixel shows.
//   MODE_ACCUMULATE: the ternary depth test of 3.2.3 against that interval. A fragment whose
//       interval overlaps it (front <= its back) lies inside and blends: it adds w * albedo,
//       w * normal and w with 32-bit atomics (fixed point). A fragment entirely behind it is
//       discarded. A fragment entirely in front would have replaced it, so after the
//       visibility pass none is left: the front-most interval is the one every fragment that
//       would have replaced the pixel's contents leads to, whatever the order, and the sums are
//       order-independent. Deviation from the sequential test: the interval blended fragments
//       are compared against is the front-most fragment's own, not one grown by the fragments
//       blended before (whose extent the paper leaves open).
// Core and halo fragments: the prefilter widens every footprint by about a pixel beyond the
// surface the splat reconstructs. A fragment whose pixel centre lies inside the splat's
// unfiltered footprint (J V_r J^T at the cutoff) is a core fragment; the others are halo. A halo key carries EWA_HALO_BIT and so loses the
// visibility test to every core key, however near: the halo of a nearer surface never hides
// the surface a pixel shows, and only a pixel that no core fragment reaches (a gap between
// minified splats, or beyond a silhouette) is decided by halos. In the accumulation halo
// fragments in front of the visible interval still blend, with their small weights: the
// filtered mix of an occluding edge.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "streams.glsl"

layout(local_size_x = RASTER_GROUP) in;

#define MODE_VISIBILITY 0u
#define MODE_ACCUMULATE 1u
layout(constant_id = EWA_SPEC_MODE) const uint MODE = MODE_VISIBILITY;
// One workgroup per splat of the large splats' list (dispatched indirectly) instead of one per
// batch.
layout(constant_id = EWA_SPEC_LARGE) const bool LARGE = false;
// The accumulation blends each fragment's lit color (lit at the point of the splat's plane the
// pixel sees with the splat's linear normal field, as Phong splatting does: the shaded surface
// is what is filtered, as the ground truth's supersampling filters shaded samples) instead of
// its albedo, for deferred lighting.
layout(constant_id = EWA_SPEC_SHADE_FRAGMENTS) const bool SHADE_FRAGMENTS = true;

layout(std430, set = 0, binding = BINDING_BATCHES) readonly buffer Batches { GpuBatch batches[]; };
layout(std430, set = 0, binding = BINDING_VISIBILITY) buffer Visibility { uint64_t keys[]; };
layout(std430, set = 0, binding = BINDING_ACCUM) buffer Accum { uint accum[]; };
// The large splats: x = workgroups to dispatch (at most 65,535), y = z = 1, w = splats listed,
// then their indices.
layout(std430, set = 0, binding = BINDING_EWA_LARGE) buffer Large {
    uint header[4];
    uint list[];
} large;

layout(push_constant) uniform Push { EwaParams p; } pc;

// Set in a halo fragment's key (the sign bit of its front depth, always 0 otherwise).
const uint64_t EWA_HALO_BIT = 1ul << 63;

// One splat set up for rasterization.
struct Splat {
    // View-space centre and the unit normal turned towards the camera.
    vec3 p;
    vec3 n;
    // Window coordinates of the projected centre, in pixels.
    vec2 centre;
    // The inverse of the resampling filter's covariance V_rho: x^T V_rho^-1 x = a x^2 +
    // 2 b x y + c y^2 with (a, b, c).
    vec3 conic;
    // The same for the unfiltered footprint J V_r J^T (the core fragments); zero when the
    // splat is seen edge-on; the filtered one for a splat of radius 0.
    vec3 core;
    // Normalization of the resampling kernel (see `setup`).
    float scale;
    // Object-space standard deviation of the reconstruction kernel.
    float sigma;
    // Linear depth range of the truncated disc (Räsänen's min and max depth of the splat).
    float zmin;
    float zmax;
    // Inclusive pixel bounding box of the truncated ellipse, inside the viewport.
    ivec2 lo;
    ivec2 hi;
    // The box reaches further than EWA_MAX_RADIUS pixels from the centre.
    bool large;
    // The splat's normal faces the camera (before it was turned towards it).
    bool facing;
    // The linear normal field (src/scene/normal_field.rs) as a view-space matrix, turned with
    // the normal: the normal at the plane's point q is n + field (q - p). Set only where
    // fragments are shaded.
    mat3 field;
};

// Sets up splat `i`; false when it is clipped or covers no pixel centre.
bool setup(uint i, out Splat s) {
    vec3 local = stream_position(i);
    if (!point_kept(i, local)) {
        return false;
    }
    s.p = (frame.u.view * vec4(local, 1.0)).xyz;
    vec4 c = frame.u.proj * vec4(s.p, 1.0);
    // Splats are clipped by their centre at the near plane (reversed infinite Z).
    if (c.w <= 0.0 || c.z > c.w) {
        return false;
    }
    // Without normals a splat is a disc facing the viewer.
    s.n = (frame.u.flags & FLAG_HAS_NORMALS) != 0u
        ? normalize(mat3(frame.u.view) * stream_normal(i)) : -normalize(s.p);
    s.facing = dot(s.n, s.p) <= 0.0;
    if (!s.facing) {
        s.n = -s.n;
    }
    s.field = mat3(0.0);
    bool has_normals = (frame.u.flags & FLAG_HAS_NORMALS) != 0u;
    if (MODE == MODE_ACCUMULATE && SHADE_FRAGMENTS && has_normals) {
        s.field = (s.facing ? 1.0 : -1.0) * stream_normal_field_view(i);
    }
    // Local parametrization (3.1.1): an orthonormal tangent frame of the splat's plane.
    mat2x3 frame_uv = tangent_frame(s.n);
    vec3 tu = frame_uv[0];
    vec3 tv = frame_uv[1];
    // Reconstruction kernel V_r = r^2 I in tangent coordinates (eq. 3.30).
    s.sigma = pc.p.radius * stream_radius(i);
    // Jacobian of the local affine approximation of the projection (eq. 3.25): derivatives of
    // the window coordinates with respect to the tangent coordinates (u, v) at the centre.
    vec2 half_size = frame.u.viewport.xy * 0.5;
    vec4 du = frame.u.proj * vec4(tu, 0.0);
    vec4 dv = frame.u.proj * vec4(tv, 0.0);
    float w2 = c.w * c.w;
    mat2 jacobian = mat2((du.xy * c.w - c.xy * du.w) / w2 * half_size,
                         (dv.xy * c.w - c.xy * dv.w) / w2 * half_size);
    // Resampling filter V_rho = J V_r J^T + V_h (eq. 3.23), the prefilter V_h = h^2 I in pixels
    // (eq. 3.31: the identity in pixel units for h = 1).
    float h2 = pc.p.prefilter * pc.p.prefilter;
    mat2 v = s.sigma * s.sigma * jacobian * transpose(jacobian) + mat2(h2, 0.0, 0.0, h2);
    float det = determinant(v);
    if (!(det > 0.0)) {
        return false;
    }
    s.conic = vec3(v[1][1], -v[0][1], v[0][0]) / det;
    mat2 vr = v - mat2(h2, 0.0, 0.0, h2);
    float det_r = determinant(vr);
    s.core = det_r > 1e-12 * det ? vec3(vr[1][1], -vr[0][1], vr[0][0]) / det_r : vec3(0.0);
    // A splat without a radius is a point sample: its footprint is the prefilter's.
    if (s.sigma <= 0.0) {
        s.core = s.conic;
    }
    // The kernel rho_k = |J| / (2 pi sqrt|V_rho|) exp(-d^2 / 2) of a normalized object-space
    // Gaussian (eqs. 3.10, 3.29), times 2 pi sigma^2: each reconstruction kernel has unit peak
    // rather than unit integral (deviation: weights in (0, 1] for the fixed-point sums; on a
    // surface of uniform sampling density the common factor cancels in the normalization,
    // eq. 3.36). Minified splats keep the weight of the screen area they cover.
    s.scale = abs(determinant(jacobian)) * s.sigma * s.sigma / sqrt(det);
    s.centre = c.xy / c.w * half_size + half_size;
    // Depth range of the disc truncated at `cutoff` standard deviations.
    float reach = pc.p.cutoff * s.sigma * sqrt(max(1.0 - s.n.z * s.n.z, 0.0));
    s.zmin = -s.p.z - reach;
    s.zmax = -s.p.z + reach;
    // Bounding box of the isocontour at the cutoff (the ellipse x^T V^-1 x = cutoff^2 spans
    // cutoff * sqrt(V_xx) and cutoff * sqrt(V_yy)), cut to the viewport.
    vec2 extent = pc.p.cutoff * sqrt(vec2(v[0][0], v[1][1]));
    s.large = any(greaterThan(extent, vec2(EWA_MAX_RADIUS)));
    vec2 lo = max(ceil(s.centre - extent - 0.5), vec2(0.0));
    vec2 hi = min(floor(s.centre + extent - 0.5), frame.u.viewport.xy - 1.0);
    if (any(greaterThan(lo, hi))) {
        return false;
    }
    s.lo = ivec2(lo);
    s.hi = ivec2(hi);
    return true;
}

// Linear depth of the splat's plane along the ray through the centre of pixel `px`, clamped to
// the splat's depth range (beyond the disc, where the prefilter widens the footprint, and for
// planes seen edge-on).
float plane_depth(Splat s, ivec2 px) {
    vec2 ndc = (vec2(px) + 0.5) * frame.u.viewport.zw * 2.0 - 1.0;
    vec3 ray = vec3(ndc.x / frame.u.proj[0][0], ndc.y / frame.u.proj[1][1], -1.0);
    float facing = dot(s.n, ray);
    float z = facing < 0.0 ? dot(s.n, s.p) / facing : s.zmax;
    return clamp(z, s.zmin, s.zmax);
}

// Rasterizes splat `s` at pixel (x, y) of its box: the fragment's visibility key or, after the
// visibility pass, its contribution.
void fragment(Splat s, vec3 albedo, int x, int y) {
    vec2 d = vec2(x, y) + 0.5 - s.centre;
    float d2 = s.conic.x * d.x * d.x + 2.0 * s.conic.y * d.x * d.y + s.conic.z * d.y * d.y;
    if (d2 > pc.p.cutoff * pc.p.cutoff) {
        return;
    }
    uint pixel = uint(y) * uint(frame.u.viewport.x) + uint(x);
    // The fragment's depth interval: the splat plane's depth at the pixel plus and minus
    // `interval` standard deviations (an adaptive interval, 3.2.3, in place of a fixed
    // epsilon, eq. 3.37). `precise`: every pass computes the same bits.
    precise float z = plane_depth(s, ivec2(x, y));
    precise float half_width = pc.p.interval * s.sigma;
    // Positive floats order like their bits; an interval reaching behind the eye starts at 0.
    precise float front = max(z - half_width, 0.0);
    precise float back = z + half_width;
    if (MODE == MODE_VISIBILITY) {
        uint64_t key = (uint64_t(floatBitsToUint(front)) << 32) | uint64_t(floatBitsToUint(back));
        float core = s.core.x * d.x * d.x + 2.0 * s.core.y * d.x * d.y + s.core.z * d.y * d.y;
        if (s.core == vec3(0.0) || core > pc.p.cutoff * pc.p.cutoff) {
            key |= EWA_HALO_BIT;
        }
        if (key < keys[pixel]) {
            atomicMin(keys[pixel], key);
        }
        return;
    }
    // Behind the nearest interval: another surface, discarded.
    float nearest_back = uintBitsToFloat(uint(keys[pixel] & 0xffffffffu));
    if (front > nearest_back) {
        return;
    }
    // Inside: blend with the Gaussian weight. Every fragment adds at least one unit, so the
    // nearest fragment always leaves a weight to divide by.
    float w = s.scale * exp(-0.5 * d2);
    uint wq = max(uint(round(w * float(EWA_WEIGHT_SCALE))), 1u);
    vec3 value = albedo;
    vec3 n = s.n;
    if (SHADE_FRAGMENTS) {
        vec2 ndc = (vec2(x, y) + 0.5) * frame.u.viewport.zw * 2.0 - 1.0;
        vec3 view_pos = vec3(ndc.x * z / frame.u.proj[0][0], ndc.y * z / frame.u.proj[1][1], -z);
        n = normalize(s.n + s.field * (view_pos - s.p));
        value = clamp(shade(albedo, n, view_pos), 0.0, 1.0);
    }
    uvec3 color = uvec3(round(value * float(wq)));
    ivec3 normal = ivec3(round(n * float(wq)));
    uint a = 8u * pixel;
    atomicAdd(accum[a], color.r);
    atomicAdd(accum[a + 1u], color.g);
    atomicAdd(accum[a + 2u], color.b);
    atomicAdd(accum[a + 3u], wq);
    atomicAdd(accum[a + 4u], uint(normal.x));
    atomicAdd(accum[a + 5u], uint(normal.y));
    atomicAdd(accum[a + 6u], uint(normal.z));
    // The coverage weight: front-facing splats only, so that beyond a silhouette the halos of
    // the surface's front and back sheets do not add up to an interior pixel's weight.
    if (s.facing) {
        atomicAdd(accum[a + 7u], wq);
    }
}

vec3 albedo_of(uint i) {
    return MODE == MODE_ACCUMULATE ? clamp(stream_albedo(i), 0.0, 1.0) : vec3(0.0);
}

void main() {
    if (LARGE) {
        // Every thread sets up the listed splat and takes every RASTER_GROUP-th pixel of its box.
        for (uint k = gl_WorkGroupID.x; k < large.header[3]; k += gl_NumWorkGroups.x) {
            uint i = large.list[k];
            Splat s;
            if (!setup(i, s)) {
                continue;
            }
            vec3 albedo = albedo_of(i);
            uint width = uint(s.hi.x - s.lo.x + 1);
            uint count = width * uint(s.hi.y - s.lo.y + 1);
            for (uint p = gl_LocalInvocationIndex; p < count; p += RASTER_GROUP) {
                fragment(s, albedo, s.lo.x + int(p % width), s.lo.y + int(p / width));
            }
        }
        return;
    }
    uint b = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (b >= frame.u.batch_count) {
        return;
    }
    GpuBatch batch = batches[b];
    for (uint k = gl_LocalInvocationIndex; k < batch.count; k += RASTER_GROUP) {
        uint i = batch.first + k;
        Splat s;
        if (!setup(i, s)) {
            continue;
        }
        if (s.large) {
            // Listed once, by the visibility pass; both passes rasterize it in the LARGE variant.
            if (MODE == MODE_VISIBILITY) {
                uint slot = atomicAdd(large.header[3], 1u);
                large.list[slot] = i;
                atomicMax(large.header[0], min(slot + 1u, 65535u));
            }
            continue;
        }
        vec3 albedo = albedo_of(i);
        for (int y = s.lo.y; y <= s.hi.y; ++y) {
            for (int x = s.lo.x; x <= s.hi.x; ++x) {
                fragment(s, albedo, x, y);
            }
        }
    }
}

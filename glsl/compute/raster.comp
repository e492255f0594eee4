#version 460
// Compute rasterizer (Schütz, Kerbl, Wimmer 2021; Schütz et al. 2022). One workgroup per batch
// of Morton-ordered points: the batch box is frustum-culled, its projected size picks how many
// quantized position words to read (4, 8 or 12 bytes per point), then every point is projected
// to its pixel.
//   MODE_VISIBILITY: 64-bit atomicMin of (linear depth bits << 32 | point index), after a plain
//                    read that skips points already behind the stored one (early depth).
//   MODE_ACCUMULATE: high-quality blending; every point within `tolerance` (relative) of the
//                    pixel's nearest depth adds its linear albedo and normal with atomics.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
#include "streams.glsl"

layout(local_size_x = RASTER_GROUP) in;

#define MODE_VISIBILITY 0u
#define MODE_ACCUMULATE 1u
layout(constant_id = RASTER_SPEC_MODE) const uint MODE = MODE_VISIBILITY;
// Read the quantized position words (true) or the f32 position stream (false).
layout(constant_id = RASTER_SPEC_QUANTIZED) const bool QUANTIZED = true;
// Back-face culling by normal (the pyramid's projection, 000 4.2.1): reads the normal stream
// (4 more bytes per point) and skips points whose normal faces away from the eye.
layout(constant_id = RASTER_SPEC_CULL) const bool CULL = false;
// Hybrid scenes: skip the points a face references (drawn as triangles), one bit per point.
layout(constant_id = RASTER_SPEC_SKIP) const bool SKIP_FACE_VERTICES = false;

layout(std430, set = 0, binding = BINDING_BATCHES) readonly buffer Batches { GpuBatch batches[]; };
layout(std430, set = 0, binding = BINDING_VISIBILITY) buffer Visibility { uint64_t keys[]; };
layout(std430, set = 0, binding = BINDING_ACCUM) buffer Accum { uint accum[]; };
layout(std430, set = 0, binding = BINDING_FACE_VERTICES) readonly buffer FaceVertices {
    uint face_vertex[];
};

layout(push_constant) uniform Push { float tolerance; } pc;

// Clip-space corner `k` of the box lo..hi.
vec4 corner(vec3 lo, vec3 hi, uint k) {
    vec3 c = vec3((k & 1u) != 0u ? hi.x : lo.x, (k & 2u) != 0u ? hi.y : lo.y,
                  (k & 4u) != 0u ? hi.z : lo.z);
    return frame.u.view_proj * vec4(c, 1.0);
}

void main() {
    uint b = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (b >= frame.u.batch_count) {
        return;
    }
    GpuBatch batch = batches[b];
    vec3 lo = vec3(batch.min_x, batch.min_y, batch.min_z);
    vec3 hi = vec3(batch.max_x, batch.max_y, batch.max_z);

    // Frustum culling: the batch is skipped when all corners lie outside one clip plane
    // (left, right, bottom, top, near; reversed infinite Z has no far plane).
    bvec4 all_out_xy = bvec4(true);
    bool all_out_near = true;
    bool behind = false;
    vec2 smin = vec2(1e30), smax = vec2(-1e30);
    for (uint k = 0u; k < 8u; ++k) {
        vec4 c = corner(lo, hi, k);
        all_out_xy = bvec4(all_out_xy.x && c.x < -c.w, all_out_xy.y && c.x > c.w,
                           all_out_xy.z && c.y < -c.w, all_out_xy.w && c.y > c.w);
        all_out_near = all_out_near && c.z > c.w;
        behind = behind || c.w <= 0.0;
        vec2 s = c.xy / max(c.w, 1e-30);
        smin = min(smin, s);
        smax = max(smax, s);
    }
    if (any(all_out_xy) || all_out_near) {
        return;
    }
    // Words of precision: the fewest whose cell spans at most half a pixel of the box's
    // projected extent (perspective magnifies the near side of a deep box beyond its average,
    // so the margin keeps every point within a pixel of its exact position).
    uint words = 3u;
    if (!behind) {
        vec2 px = (smax - smin) * 0.5 * frame.u.viewport.xy;
        float extent = 2.0 * max(px.x, px.y);
        words = extent <= float(1u << QUANT_BITS) ? 1u
              : extent <= float(1u << (2u * QUANT_BITS)) ? 2u : 3u;
    }

    uint s = segment_of(batch.first);
    uint base = segments[s].color_first.z;
    WordStream coarse = WordStream(segments[s].position_coarse.zw);
    WordStream medium = WordStream(segments[s].medium_fine.xy);
    WordStream fine = WordStream(segments[s].medium_fine.zw);
    FloatStream exact = FloatStream(segments[s].position_coarse.xy);
    uvec4 classes = segments[s].classes;
    ivec2 size = ivec2(frame.u.viewport.xy);

    for (uint k = gl_LocalInvocationIndex; k < batch.count; k += RASTER_GROUP) {
        uint i = batch.first + k;
        uint l = i - base;
        vec3 p;
        if (QUANTIZED) {
            uvec3 w = uvec3(coarse.v[l], words > 1u ? medium.v[l] : 0u,
                            words > 2u ? fine.v[l] : 0u);
            p = dequantize(w, words, lo, hi - lo);
        } else {
            p = vec3(exact.v[3u * l], exact.v[3u * l + 1u], exact.v[3u * l + 2u]);
        }
        vec4 c = frame.u.view_proj * vec4(p, 1.0);
        // Points are clipped by their centre, like hardware points.
        if (c.w <= 0.0 || c.z > c.w || any(greaterThan(abs(c.xy), vec2(c.w)))) {
            continue;
        }
        vec2 half_size = frame.u.viewport.xy * 0.5;
        vec2 win = c.xy / c.w * half_size + half_size;
        // The pixel whose centre a 1-pixel point square covers, with the square's corner snapped
        // to the 1/256-pixel grid of hardware rasterizers and the top-left fill rule, so a point
        // lands where the point pipeline puts it.
        vec2 corner = round((win - 0.5) * 256.0) / 256.0;
        ivec2 px = ivec2(ceil(corner - 0.5));
        if (any(lessThan(px, ivec2(0))) || any(greaterThanEqual(px, size))) {
            continue;
        }
        if (SKIP_FACE_VERTICES && (face_vertex[i >> 5u] & (1u << (i & 31u))) != 0u) {
            continue;
        }
        if (!clip_kept(p) || !class_kept(classes, l)) {
            continue;
        }
        if (CULL && (frame.u.flags & FLAG_HAS_NORMALS) != 0u) {
            vec3 n = mat3(frame.u.view) * stream_normal(i);
            if (dot(n, (frame.u.view * vec4(p, 1.0)).xyz) > 0.0) {
                continue;
            }
        }
        uint pixel = uint(px.y) * uint(size.x) + uint(px.x);
        if (MODE == MODE_VISIBILITY) {
            uint64_t key = (uint64_t(floatBitsToUint(c.w)) << 32) | uint64_t(i);
            if (key < keys[pixel]) {
                atomicMin(keys[pixel], key);
            }
        } else {
            float nearest = uintBitsToFloat(uint(keys[pixel] >> 32));
            if (c.w > nearest * (1.0 + pc.tolerance)) {
                continue;
            }
            vec3 view_pos = (frame.u.view * vec4(p, 1.0)).xyz;
            vec3 n = mat3(frame.u.view) * stream_normal(i);
            // Two-sided: face the viewer before averaging, so opposite normals don't cancel.
            n = dot(n, view_pos) > 0.0 ? -n : n;
            uvec3 albedo = uvec3(round(clamp(stream_albedo(i), 0.0, 1.0) * 255.0));
            ivec3 normal = ivec3(round(n * 1024.0));
            uint a = 8u * pixel;
            atomicAdd(accum[a], albedo.r);
            atomicAdd(accum[a + 1u], albedo.g);
            atomicAdd(accum[a + 2u], albedo.b);
            atomicAdd(accum[a + 3u], 1u);
            atomicAdd(accum[a + 4u], uint(normal.x));
            atomicAdd(accum[a + 5u], uint(normal.y));
            atomicAdd(accum[a + 6u], uint(normal.z));
        }
    }
}

#version 460
// EWA splatting, normalization and deferred lighting (000 §3.2.3, eq. 3.36): the accumulated
// weighted albedo and normal are divided by the weight sum and shaded per pixel with the
// frame's lights at the depth of the pixel's front-most fragment.
// Coverage: a pixel shows the surface when a core fragment reached it (its centre lies on the
// surface the splats' unfiltered footprints cover), or when only halo fragments did but the
// weight sum of the front-facing ones reaches COVERAGE, half the sum a pixel inside a uniformly sampled surface
// collects (the kernels sum to the surface's indicator filtered by the resampling filter: 1
// inside, 1/2 on a straight edge), which closes gaps between minified splats. Beyond a
// silhouette only the prefilter's halo reaches a pixel, with less: it stays empty, so the
// prefilter smooths the silhouette instead of dilating it by its width. Zwicker et al. blend
// such pixels with the background by the weight sum (alpha); the half-coverage rule is the
// `mesh` ground truth's (at least half the pixel's samples).
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "streams.glsl"

layout(local_size_x = RESOLVE_GROUP, local_size_y = RESOLVE_GROUP) in;

// Half the weight sum of a pixel inside the surface, in the accumulators' fixed-point units.
layout(constant_id = EWA_SPEC_COVERAGE) const float COVERAGE = 0.0;
// The accumulators hold lit colors (splat.comp's SHADE_FRAGMENTS): normalized, not lit again.
layout(constant_id = EWA_SPEC_SHADED) const bool SHADED = true;

layout(std430, set = 0, binding = BINDING_VISIBILITY) readonly buffer Visibility {
    uint64_t keys[];
};
layout(std430, set = 0, binding = BINDING_ACCUM) readonly buffer Accum { uint accum[]; };
layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;
layout(set = 0, binding = BINDING_OUTPUT0 + 1, r32f) uniform writeonly image2D out_depth;
layout(set = 0, binding = BINDING_OUTPUT0 + 2, rgba16f) uniform writeonly image2D out_normal;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    uint pixel = uint(px.y) * uint(size.x) + uint(px.x);
    uint64_t key = keys[pixel];
    uint a = 8u * pixel;
    bool halo = (key >> 63) != 0ul;
    if (key == ~0ul || (halo && float(accum[a + 7u]) < COVERAGE)) {
        imageStore(out_color, px, vec4(0.0));
        imageStore(out_depth, px, vec4(0.0));
        imageStore(out_normal, px, vec4(0.0));
        return;
    }
    // The front-most fragment's interval is centred on its plane's depth at the pixel (an
    // interval cut at the eye, front = 0, gives a midpoint nearer than that plane but still
    // inside the interval).
    float front = uintBitsToFloat(uint(key >> 32) & 0x7fffffffu);
    float back = uintBitsToFloat(uint(key & 0xffffffffu));
    float depth = 0.5 * (front + back);
    float weight = float(max(accum[a + 3u], 1u));
    // The filtered albedo, or the filtered lit color when the fragments were shaded.
    vec3 filtered = vec3(accum[a], accum[a + 1u], accum[a + 2u]) / weight;
    vec2 ndc = (vec2(px) + 0.5) * frame.u.viewport.zw * 2.0 - 1.0;
    vec3 view_pos = vec3(ndc.x * depth / frame.u.proj[0][0], ndc.y * depth / frame.u.proj[1][1],
                         -depth);
    vec3 sum = vec3(ivec3(accum[a + 4u], accum[a + 5u], accum[a + 6u]));
    vec3 n = length(sum) > 0.0 ? normalize(sum) : normalize(-view_pos);
    vec3 color = SHADED ? filtered : shade(filtered, n, view_pos);
    imageStore(out_color, px, vec4(linear_to_srgb(color), 1.0));
    imageStore(out_depth, px, vec4(depth));
    imageStore(out_normal, px, vec4(n, 1.0));
}

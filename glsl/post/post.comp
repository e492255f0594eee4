#version 460
// The post-processing stage, run on every method's standard targets: eye-dome lighting
// (Boucheny 2009) and the background composite, selected by specialization constants.
//
// Eye-dome lighting as Potree (src/materials/shaders/edl.fs) and CloudCompare (qEDL) ship it:
// depth is compared in log2 of the linear view depth; each of the EDL_NEIGHBOURS neighbours on a
// circle of `radius` pixels (offsets rounded on the host, image edges clamped) that is nearer
// than the pixel adds log2(d) - log2(d_n); background neighbours add nothing (infinitely far);
// the color is multiplied by exp(-300 strength sum / EDL_NEIGHBOURS) in its sRGB encoding, as
// the references multiply their display colors. Background pixels stay background.
#include "shared.glsl"

layout(local_size_x = POST_GROUP, local_size_y = POST_GROUP) in;

layout(constant_id = POST_SPEC_EDL) const bool EDL = false;
layout(constant_id = POST_SPEC_BACKGROUND) const bool BACKGROUND = false;

layout(set = 0, binding = BINDING_INPUT0, rgba8) uniform readonly image2D in_color;
layout(set = 0, binding = BINDING_INPUT1, r32f) uniform readonly image2D in_depth;
layout(set = 0, binding = BINDING_OUTPUT0, rgba8) uniform writeonly image2D out_color;

layout(push_constant) uniform Push { PostParams p; } pc;

// The scale of the references' response: shade = exp(-EDL_SCALE * strength * mean response).
const float EDL_SCALE = 300.0;

float edl_response(ivec2 px, ivec2 size, float depth) {
    float log_depth = log2(depth);
    vec4 pairs[EDL_NEIGHBOURS / 2] =
        vec4[](pc.p.offsets01, pc.p.offsets23, pc.p.offsets45, pc.p.offsets67);
    float sum = 0.0;
    for (int i = 0; i < EDL_NEIGHBOURS; ++i) {
        vec4 pair = pairs[i / 2];
        ivec2 offset = ivec2((i % 2) == 0 ? pair.xy : pair.zw);
        float d = imageLoad(in_depth, clamp(px + offset, ivec2(0), size - 1)).r;
        // max(0, log2 depth - log2 d) without a logarithm where it is 0 (flat regions).
        if (d > 0.0 && d < depth) {
            sum += max(0.0, log_depth - log2(d));
        }
    }
    return sum / float(EDL_NEIGHBOURS);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(out_color);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    float depth = imageLoad(in_depth, px).r;
    if (!(depth > 0.0)) {
        imageStore(out_color, px, BACKGROUND ? pc.p.background : imageLoad(in_color, px));
        return;
    }
    vec4 color = imageLoad(in_color, px);
    if (EDL) {
        float response = edl_response(px, size, depth);
        color.rgb *= exp(-EDL_SCALE * pc.p.strength * response);
    }
    if (BACKGROUND) {
        color.a = 1.0;
    }
    imageStore(out_color, px, color);
}

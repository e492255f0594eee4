// Point streams (src/streams): every attribute in its own buffer, reached through the device
// addresses of the segment table; batches of BATCH_POINTS Morton-ordered points with bounds.
#ifndef SURFEL_STREAMS_GLSL
#define SURFEL_STREAMS_GLSL
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#include "common.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer WordStream {
    uint v[];
};
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FloatStream {
    float v[];
};

layout(std430, set = 0, binding = BINDING_SEGMENTS) readonly buffer Segments {
    GpuSegment segments[];
};

// Segment of point `i` and its index inside the segment.
uint segment_of(uint i) { return i / frame.u.segment_points; }
uint local_index(uint i, uint s) { return i - segments[s].color_first.z; }

vec3 stream_position(uint i) {
    uint s = segment_of(i);
    uint l = 3u * local_index(i, s);
    FloatStream f = FloatStream(segments[s].position_coarse.xy);
    return vec3(f.v[l], f.v[l + 1u], f.v[l + 2u]);
}

vec3 stream_normal(uint i) {
    uint s = segment_of(i);
    return oct_decode(WordStream(segments[s].normal_radius.xy).v[local_index(i, s)]);
}

float stream_radius(uint i) {
    uint s = segment_of(i);
    uint l = local_index(i, s);
    vec2 pair = unpackHalf2x16(WordStream(segments[s].normal_radius.zw).v[l >> 1u]);
    return (l & 1u) == 0u ? pair.x : pair.y;
}

// Albedo in linear space: the point's color when the frame uses colors, else the base color.
vec3 stream_albedo(uint i) {
    if ((frame.u.flags & FLAG_USE_COLOR) != 0u) {
        uint s = segment_of(i);
        uint c = WordStream(segments[s].color_first.xy).v[local_index(i, s)];
        return srgb_to_linear(unpackUnorm4x8(c).rgb);
    }
    return frame.u.base_color.rgb;
}

// Centre of the quantized cell of `words` words (1..3) of QUANT_BITS per axis, x lowest
// (mirrors `dequantize` in src/streams/mod.rs).
vec3 dequantize(uvec3 w, uint words, vec3 lo, vec3 extent) {
    uint mask = (1u << QUANT_BITS) - 1u;
    uvec3 q = uvec3(0u);
    for (uint k = 0u; k < words; ++k) {
        uvec3 part = uvec3(w[k], w[k] >> QUANT_BITS, w[k] >> (2u * QUANT_BITS)) & mask;
        q = (q << QUANT_BITS) | part;
    }
    return lo + extent * (vec3(q) + 0.5) / float(1u << (QUANT_BITS * words));
}
#endif

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

// The linear normal field of Phong splatting (src/scene/normal_field.rs): the shape operator
// [[a, b], [b, c]] in the tangent frame of the stored normal, times the splat radius.
vec3 stream_normal_field(uint i) {
    uint s = segment_of(i);
    uint l = 2u * local_index(i, s);
    WordStream w = WordStream(segments[s].normal_field.xy);
    return vec3(unpackHalf2x16(w.v[l]), unpackHalf2x16(w.v[l + 1u]).x);
}

// Point i's linear normal field as a view-space matrix M: the normal at a point q of the
// splat's plane is n + M (q - p), n the stored normal in view space. With the operator
// S = [[a, b], [b, c]] in the tangent frame (t_u, t_v) of the stored normal (the stream holds S
// times the stored radius), M = (a t_u + b t_v) t_u^T + (b t_u + c t_v) t_v^T, the frame
// rotated to view space. Zero for a splat without a radius.
mat3 stream_normal_field_view(uint i) {
    float r = stream_radius(i);
    if (r <= 0.0) {
        return mat3(0.0);
    }
    vec3 s = stream_normal_field(i) / r;
    mat3 view = mat3(frame.u.view);
    mat2x3 t = tangent_frame(stream_normal(i));
    vec3 tu = view * t[0];
    vec3 tv = view * t[1];
    return outerProduct(s.x * tu + s.y * tv, tu) + outerProduct(s.y * tu + s.z * tv, tv);
}

// The f32 value of the scalar field uploaded for coloring (GpuSegment.scalar).
float stream_scalar(uint i) {
    uint s = segment_of(i);
    return FloatStream(segments[s].scalar.xy).v[local_index(i, s)];
}

// Whether the class filter keeps point l of a segment whose `GpuSegment.classes` is `classes`
// (a segment without the class stream keeps every point).
bool class_kept(uvec4 classes, uint l) {
    if ((frame.u.flags & FLAG_FILTER) == 0u || classes.w == 0u) {
        return true;
    }
    uint c = (WordStream(classes.xy).v[l >> 2u] >> (8u * (l & 3u))) & 255u;
    uvec4 words = c < 128u ? frame.u.class_hidden_lo : frame.u.class_hidden_hi;
    return (words[(c >> 5u) & 3u] & (1u << (c & 31u))) == 0u;
}

// Whether the viewer's clipping box and class filter keep point i at local position p
// (src/scene/clip.rs, `Resolved::keeps`). Dynamically uniform branches: without a filter
// nothing more is read; with hidden classes one byte per point.
bool point_kept(uint i, vec3 p) {
    if (!clip_kept(p)) {
        return false;
    }
    if ((frame.u.flags & FLAG_FILTER) == 0u) {
        return true;
    }
    uint s = segment_of(i);
    return class_kept(segments[s].classes, local_index(i, s));
}

// Albedo in linear space, selected by the frame's color mode (src/color.rs): the point's color,
// the base color, or an attribute through a palette or ramp.
vec3 stream_albedo(uint i) {
    uint mode = frame.u.color_mode;
    if (mode == COLOR_RGB) {
        uint s = segment_of(i);
        uint c = WordStream(segments[s].color_first.xy).v[local_index(i, s)];
        return srgb_to_linear(unpackUnorm4x8(c).rgb);
    }
    if (mode == COLOR_INTENSITY) {
        float t = ramp_position(stream_scalar(i));
        return srgb_to_linear(vec3(isnan(t) ? 0.0 : clamp(t, 0.0, 1.0)));
    }
    if (mode == COLOR_SCALAR) {
        return ramp(ramp_position(stream_scalar(i)));
    }
    if (mode == COLOR_CLASSIFICATION) {
        const uint palette[20] = uint[](
            CLASS_COLOR_0, CLASS_COLOR_1, CLASS_COLOR_2, CLASS_COLOR_3, CLASS_COLOR_4,
            CLASS_COLOR_5, CLASS_COLOR_6, CLASS_COLOR_7, CLASS_COLOR_8, CLASS_COLOR_9,
            CLASS_COLOR_10, CLASS_COLOR_11, CLASS_COLOR_12, CLASS_COLOR_13, CLASS_COLOR_14,
            CLASS_COLOR_15, CLASS_COLOR_16, CLASS_COLOR_17, CLASS_COLOR_18, CLASS_COLOR_OTHER);
        float c = stream_scalar(i);
        bool known = c >= 0.0 && c <= 18.0 && c == floor(c);
        return rgb8(palette[known ? uint(c) : 19u]);
    }
    if (mode == COLOR_RETURN) {
        const uint palette[6] = uint[](RETURN_COLOR_0, RETURN_COLOR_1, RETURN_COLOR_2,
                                       RETURN_COLOR_3, RETURN_COLOR_4, RETURN_COLOR_5);
        float r = stream_scalar(i);
        return rgb8(palette[r >= 1.0 ? min(uint(r), 5u) : 0u]);
    }
    if (mode == COLOR_ELEVATION) {
        return elevation_albedo(stream_position(i));
    }
    if (mode == COLOR_NORMAL) {
        return normal_albedo(stream_normal(i));
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

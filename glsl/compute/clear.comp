#version 460
// Clears the visibility buffer to "empty" (all ones) and, for the high-quality mode, the
// accumulators to zero: one thread per pixel.
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "common.glsl"

layout(local_size_x = 256) in;

layout(constant_id = 0) const bool HIGH_QUALITY = false;

layout(std430, set = 0, binding = BINDING_VISIBILITY) writeonly buffer Visibility {
    uint64_t keys[];
};
layout(std430, set = 0, binding = BINDING_ACCUM) writeonly buffer Accum { uvec4 accum[]; };

void main() {
    uint pixel = gl_GlobalInvocationID.x;
    if (pixel >= uint(frame.u.viewport.x) * uint(frame.u.viewport.y)) {
        return;
    }
    keys[pixel] = ~0ul;
    if (HIGH_QUALITY) {
        accum[2u * pixel] = uvec4(0u);
        accum[2u * pixel + 1u] = uvec4(0u);
    }
}

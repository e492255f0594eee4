#version 460
// The visible points are the distinct extremes (003 4.2), one thread per sector: clear the
// extreme's bit in the hidden-point mask (all set before) and count it the first time.
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(std430, set = 0, binding = BINDING_HPR_SRC) readonly buffer Final {
    uint extremes[];
};
layout(std430, set = 0, binding = BINDING_HPR_MASK) buffer Hidden {
    uint hidden[];
};

void main() {
    uint t = thread_id();
    if (t >= h.sqrt_k * h.sqrt_k) {
        return;
    }
    uint i = extremes[t];
    if (i == HPR_EMPTY) {
        return;
    }
    uint bit = 1u << (i & 31u);
    if ((atomicAnd(hidden[i >> 5], ~bit) & bit) != 0u) {
        atomicAdd(h.visible, 1u);
    }
}

#version 460
// Partial surface reconstruction (003 4.4), one thread per 2 x 2 block of sectors: the
// triangles (a, b, d) and (a, d, c) of its extremes a = MAX[i, j], b = MAX[i + 1, j],
// c = MAX[i, j + 1], d = MAX[i + 1, j + 1], dropped when a corner has no extreme, a vertex
// repeats, a vertex is behind the camera or a projected edge is longer than p.max_edge pixels
// (src/hpr/approx.rs `triangulate`). Kept triangles are appended to the index list of the
// indirect draw.
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(std430, set = 0, binding = BINDING_HPR_SRC) readonly buffer Final {
    uint extremes[];
};
layout(std430, set = 0, binding = BINDING_HPR_TRIANGLES) writeonly buffer Triangles {
    uint indices[];
};

// The pixel of point i, or a negative x behind the camera.
vec2 pixel_of(uint i) {
    vec4 c = frame.u.view_proj * vec4(stream_position(i), 1.0);
    if (c.w <= 0.0) {
        return vec2(-1e30);
    }
    return (c.xy / c.w + 1.0) * 0.5 * frame.u.viewport.xy;
}

void emit(uint a, uint b, uint c) {
    if (a == HPR_EMPTY || b == HPR_EMPTY || c == HPR_EMPTY || a == b || b == c || a == c) {
        return;
    }
    vec2 pa = pixel_of(a);
    vec2 pb = pixel_of(b);
    vec2 pc = pixel_of(c);
    if (pa.x < -1e29 || pb.x < -1e29 || pc.x < -1e29) {
        return;
    }
    float e = p.max_edge;
    if (distance(pa, pb) > e || distance(pb, pc) > e || distance(pc, pa) > e) {
        return;
    }
    uint at = atomicAdd(h.index_count, 3u);
    indices[at] = a;
    indices[at + 1u] = b;
    indices[at + 2u] = c;
}

void main() {
    uint t = thread_id();
    uint s = h.sqrt_k;
    if (s < 2u || t >= (s - 1u) * (s - 1u)) {
        return;
    }
    uint i = t / (s - 1u);
    uint j = t % (s - 1u);
    uint a = extremes[i * s + j];
    uint b = extremes[(i + 1u) * s + j];
    uint c = extremes[i * s + j + 1u];
    uint d = extremes[(i + 1u) * s + j + 1u];
    emit(a, b, d);
    emit(a, d, c);
}

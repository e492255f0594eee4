#version 460
// Propagation of extreme points (003 4.3), one thread per sector: a visited sector (its
// EMPTY cell holds a point) takes the point of its (2 REACH + 1)^2 neighbourhood that lies
// furthest along its direction (ties: the lower index); unvisited sectors keep what they
// have. FROM_MAX reads the 64-bit extremes of the sector pass (REACH 0: just their indices;
// REACH m/2: the thesis' fixed m x m gather); otherwise one adaptive round reads the previous
// round's extremes and flags a change. phi wraps around in the full-sphere partition.
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(constant_id = HPR_SPEC_REACH) const int REACH = 1;
layout(constant_id = HPR_SPEC_FROM_MAX) const bool FROM_MAX = false;
layout(constant_id = HPR_SPEC_ADAPTIVE) const bool ADAPTIVE = false;

layout(std430, set = 0, binding = BINDING_HPR_MAX) readonly buffer Extremes {
    uint64_t extremes[];
};
layout(std430, set = 0, binding = BINDING_HPR_SRC) readonly buffer Source {
    uint source[];
};
layout(std430, set = 0, binding = BINDING_HPR_DST) writeonly buffer Destination {
    uint destination[];
};
layout(std430, set = 0, binding = BINDING_HPR_EMPTY) readonly buffer Occupied {
    uint occupied[];
};

uint extreme(uint id) {
    return FROM_MAX ? key_point(extremes[id]) : source[id];
}

void main() {
    uint t = thread_id();
    uint s = h.sqrt_k;
    if (t >= s * s) {
        return;
    }
    uint i = t / s;
    uint j = t % s;
    uint own = extreme(t);
    uint best = own;
    if (REACH > 0 && occupied[empty_cell(i, j)] != 0u) {
        vec3 d = sector_dir(i, j);
        float best_dist = best == HPR_EMPTY ? 0.0 : point_along(best, d);
        for (int di = -REACH; di <= REACH; di++) {
            int a = int(i) + di;
            if (h.full != 0u) {
                a = (a + int(s)) % int(s);
            }
            if (a < 0 || a >= int(s)) {
                continue;
            }
            for (int dj = -REACH; dj <= REACH; dj++) {
                int b = int(j) + dj;
                if (b < 0 || b >= int(s)) {
                    continue;
                }
                uint c = extreme(uint(a) * s + uint(b));
                if (c == HPR_EMPTY || c == best) {
                    continue;
                }
                float c_dist = point_along(c, d);
                if (best == HPR_EMPTY || c_dist > best_dist
                    || (c_dist == best_dist && c < best)) {
                    best = c;
                    best_dist = c_dist;
                }
            }
        }
    }
    destination[t] = best;
    if (ADAPTIVE && best != own) {
        h.changed = 1u;
    }
}

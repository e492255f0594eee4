#version 460
// The complete visible set, per point, in double precision: hidden when its flipped image is
// certified strictly inside a tetrahedron of the eye and three flipped sector extremes (any
// three of the 3 x 3 sectors around its own on every grid, coarsest first: the sign of
// q . (e_x x e_y) is decided once per pair, then the triangles whose three pairs agree are
// tested against their far face); otherwise visible: its bit in the hidden mask (all set
// before) is cleared and it is counted. The CPU reference is src/hpr/prefilter.rs
// (certified_hidden, strictly_inside), formula for formula.
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = HPR_GROUP) in;

layout(std430, set = 0, binding = BINDING_HPR_COMPLETE) readonly buffer Nearest {
    uint64_t nearest[];
};
layout(std430, set = 0, binding = BINDING_HPR_MASK) buffer Hidden {
    uint hidden[];
};

// prefilter::TOLERANCE ulps of f64.
const double ULPS = 64.0lf * 2.220446049250313e-16lf;

dvec3 flipped(uint i) {
    dvec3 v = dvec3(stream_position(i)) - dvec3(h.eye_radius.xyz);
    double n = length(v);
    return v + 2.0lf * (double(h.eye_radius.w) - n) * v / n;
}

// Whether q, certainly on the inner side `sign` of the three planes through the eye and two
// of a, b, c, is strictly inside the tetrahedron (eye, a, b, c).
bool strictly_inside_cone(dvec3 q, dvec3 a, dvec3 b, dvec3 c, double sign) {
    double det = dot(a, cross(b, c));
    if (det * sign <= 0.0lf) {
        return false;
    }
    dvec3 da = a - q;
    dvec3 db = b - q;
    dvec3 dc = c - q;
    double depth = dot(da, cross(db, dc));
    return depth * sign > ULPS * length(da) * length(db) * length(dc);
}

// The bit of the pair (x, y), x < y < 9, in a 36-bit mask.
uint64_t pair_bit(int x, int y) {
    return 1ul << uint(x * (17 - x) / 2 + y - x - 1);
}

// The extreme of sector (i, j) on `level`, or HPR_EMPTY.
uint extreme(uint level, int i, int j) {
    int s = int(p.complete_side >> level);
    if (i < 0 || j < 0 || i >= s || j >= s) {
        return HPR_EMPTY;
    }
    uint64_t key = nearest[complete_offset(level) + uint(i * s + j)];
    return key == ~0ul ? HPR_EMPTY : uint(key & 0xfffffffful);
}

bool covered(dvec3 q, uint level, int i, int j) {
    dvec3 e[9];
    double norm[9];
    int m = 0;
    double reach = 0.0lf;
    for (int di = -1; di <= 1; ++di) {
        for (int dj = -1; dj <= 1; ++dj) {
            uint v = extreme(level, i + di, j + dj);
            if (v != HPR_EMPTY) {
                e[m] = flipped(v);
                norm[m] = length(e[m]);
                reach = max(reach, dot(e[m], e[m]));
                ++m;
            }
        }
    }
    // The tetrahedron lies in the ball through its farthest vertex.
    if (m < 3 || dot(q, q) >= reach) {
        return false;
    }
    // Pairs whose sign of q . (e_x x e_y) clears its rounding bound: positive, negative.
    double nq = length(q);
    uint64_t pos = 0ul;
    uint64_t neg = 0ul;
    for (int x = 0; x < m; ++x) {
        for (int y = x + 1; y < m; ++y) {
            double t = dot(q, cross(e[x], e[y]));
            double bound = ULPS * nq * norm[x] * norm[y];
            if (t > bound) {
                pos |= pair_bit(x, y);
            } else if (t < -bound) {
                neg |= pair_bit(x, y);
            }
        }
    }
    for (int x = 0; x < m; ++x) {
        for (int y = x + 1; y < m; ++y) {
            uint64_t xy = pair_bit(x, y);
            if (((pos | neg) & xy) == 0ul) {
                continue;
            }
            for (int z = y + 1; z < m; ++z) {
                uint64_t yz = pair_bit(y, z);
                uint64_t xz = pair_bit(x, z);
                if ((pos & xy) != 0ul && (pos & yz) != 0ul && (neg & xz) != 0ul
                    && strictly_inside_cone(q, e[x], e[y], e[z], 1.0lf)) {
                    return true;
                }
                if ((neg & xy) != 0ul && (neg & yz) != 0ul && (pos & xz) != 0ul
                    && strictly_inside_cone(q, e[x], e[y], e[z], -1.0lf)) {
                    return true;
                }
            }
        }
    }
    return false;
}

void main() {
    uint i = thread_id();
    if (i >= p.point_count) {
        return;
    }
    vec3 local = stream_position(i);
    vec3 v = local - h.eye_radius.xyz;
    float n = length(v);
    if (n == 0.0 || !point_kept(i, local)) {
        return;
    }
    uvec2 c = complete_cell(v, n);
    dvec3 q = flipped(i);
    for (int l = HPR_COMPLETE_LEVELS - 1; l >= 0; --l) {
        if (covered(q, uint(l), int(c.x >> uint(l)), int(c.y >> uint(l)))) {
            return;
        }
    }
    uint bit = 1u << (i & 31u);
    atomicAnd(hidden[i >> 5], ~bit);
    atomicAdd(h.visible, 1u);
}

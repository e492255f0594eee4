#version 460
// The complete visible set, per point, in double precision: hidden when its flipped image is
// certified strictly inside a tetrahedron of the eye and three flipped sector extremes (the
// 2 x 2 blocks of sectors around its own on every grid, coarsest first, each split along the
// diagonal of its outer surface); otherwise visible: its bit in the hidden mask (all set
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

bool certain(double value, double sign, double bound) {
    return value * sign > ULPS * bound;
}

bool strictly_inside(dvec3 q, dvec3 a, dvec3 b, dvec3 c) {
    double det = dot(a, cross(b, c));
    if (det == 0.0lf) {
        return false;
    }
    double sign = det > 0.0lf ? 1.0lf : -1.0lf;
    double s0 = dot(q, cross(b, c));
    double s1 = dot(a, cross(q, c));
    double s2 = dot(a, cross(b, q));
    if (s0 * sign <= 0.0lf || s1 * sign <= 0.0lf || s2 * sign <= 0.0lf) {
        return false;
    }
    dvec3 da = a - q;
    dvec3 db = b - q;
    dvec3 dc = c - q;
    double depth = dot(da, cross(db, dc));
    if (depth * sign <= 0.0lf) {
        return false;
    }
    double nq = length(q);
    double na = length(a);
    double nb = length(b);
    double nc = length(c);
    return certain(s0, sign, nq * nb * nc) && certain(s1, sign, na * nq * nc)
        && certain(s2, sign, na * nb * nq)
        && certain(depth, sign, length(da) * length(db) * length(dc));
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
    for (int b = 0; b < 4; ++b) {
        int bi = b / 2 - 1;
        int bj = b % 2 - 1;
        uint ea = extreme(level, i + bi, j + bj);
        uint eb = extreme(level, i + bi + 1, j + bj);
        uint ec = extreme(level, i + bi + 1, j + bj + 1);
        uint ed = extreme(level, i + bi, j + bj + 1);
        if (ea == HPR_EMPTY || eb == HPR_EMPTY || ec == HPR_EMPTY || ed == HPR_EMPTY) {
            continue;
        }
        dvec3 a = flipped(ea);
        dvec3 bb = flipped(eb);
        dvec3 c = flipped(ec);
        dvec3 d = flipped(ed);
        bool ridge_ac = dot(a - d, cross(bb - d, c - d)) * dot(a, cross(bb, c)) > 0.0lf;
        if (ridge_ac) {
            if (strictly_inside(q, a, bb, c) || strictly_inside(q, a, c, d)) {
                return true;
            }
        } else if (strictly_inside(q, a, bb, d) || strictly_inside(q, bb, c, d)) {
            return true;
        }
    }
    return false;
}

void main() {
    uint i = thread_id();
    if (i >= p.point_count) {
        return;
    }
    vec3 v = stream_position(i) - h.eye_radius.xyz;
    float n = length(v);
    if (n == 0.0) {
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

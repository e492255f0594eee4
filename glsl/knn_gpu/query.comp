#version 460
// k-NN, the search: one thread per point in sorted order (the threads of a workgroup share
// cells), the k nearest in the 3×3×3 block of cells around the point's own, then, where that
// cannot be verified, in the 5×5×5 block; then the PCA normal (Jacobi rotations of the 3×3
// covariance) oriented as on the CPU (src/scene/preprocess.rs), and the squared distance of
// the k-th neighbour. Exact as on the CPU: the result is kept only when the k-th neighbour
// lies within the searched block's inner bound; a point that stays unresolved (an outlier)
// is marked for the CPU's exact search.
#include "knn.glsl"

layout(constant_id = KNN_SPEC_K) const uint K = 10;

// Bucket b: [2 b] first sorted index, [2 b + 1] end.
layout(std430, set = 0, binding = BINDING_KNN_TABLE) readonly buffer Table {
    uint table[];
};
// xyz: position, w: the input index's bits.
layout(std430, set = 0, binding = BINDING_KNN_SORTED) readonly buffer Sorted {
    vec4 sorted[];
};
// Per input point, xyz: unit normal, w: squared k-th neighbour distance (< 0: unresolved).
layout(std430, set = 0, binding = BINDING_KNN_OUT) writeonly buffer Out {
    vec4 result[];
};
// Per input point, its KNN_GRAPH_K nearest neighbours' input indices, nearest first.
layout(std430, set = 0, binding = BINDING_KNN_GRAPH) writeonly buffer Graph {
    uint graph[];
};

const uint NO_NEIGHBOUR = 0xffffffffu;

const float FLT_MAX = 3.402823466e38;

// The best neighbours so far, nearest first, as (squared distance, sorted index); ties go to
// the lower index, so the result does not depend on the order buckets are visited.
float best_d[K];
uint best_s[K];
uint found = 0u;

void offer(float d, uint s) {
    if (!(d <= FLT_MAX)) {
        // NaN or infinite: a non-finite point, never a neighbour.
        return;
    }
    if (found == K) {
        float wd = best_d[K - 1u];
        if (d > wd || (d == wd && s >= best_s[K - 1u])) {
            return;
        }
    }
    // A bucket holding several searched cells is visited once per cell: keep a point once.
    for (uint j = 0u; j < found; ++j) {
        if (best_s[j] == s) {
            return;
        }
    }
    uint j = min(found, K - 1u);
    found = min(found + 1u, K);
    while (j > 0u && (best_d[j - 1u] > d || (best_d[j - 1u] == d && best_s[j - 1u] > s))) {
        best_d[j] = best_d[j - 1u];
        best_s[j] = best_s[j - 1u];
        --j;
    }
    best_d[j] = d;
    best_s[j] = s;
}

// Offers every point of the cells of the (2 r + 1)³ block around `c` except the point itself;
// past r = 1, only the cells the (2 r - 1)³ block inside it does not hold.
void search(vec3 q, uint self_s, ivec3 c, int r) {
    ivec3 lo = max(c - r, ivec3(0));
    ivec3 hi = min(c + r, ivec3(p.dims_count.xyz) - 1);
    for (int z = lo.z; z <= hi.z; ++z) {
        for (int y = lo.y; y <= hi.y; ++y) {
            for (int x = lo.x; x <= hi.x; ++x) {
                ivec3 d = abs(ivec3(x, y, z) - c);
                if (r > 1 && max(d.x, max(d.y, d.z)) < r) {
                    continue;
                }
                uint b = bucket_of(ivec3(x, y, z));
                uint end = table[2u * b + 1u];
                for (uint t = table[2u * b]; t < end; ++t) {
                    if (t != self_s) {
                        vec3 e = sorted[t].xyz - q;
                        offer(dot(e, e), t);
                    }
                }
            }
        }
    }
}

// Whether the block of radius r around `c` holds every cell.
bool covers_all(ivec3 c, int r) {
    return all(lessThanEqual(c, ivec3(r))) &&
           all(greaterThanEqual(c + r + 1, ivec3(p.dims_count.xyz)));
}

// Squared distance from `q` (in cell `c`) to the nearest face of the block of radius r beyond
// which cells exist, a hair inside (as GridFrame's inner bound on the CPU).
float inner_bound2(vec3 q, ivec3 c, int r) {
    float bound = FLT_MAX;
    vec3 at = (q - p.origin_cell.xyz) / p.origin_cell.w;
    for (int a = 0; a < 3; ++a) {
        float lo = float(c[a] - r);
        float hi = float(c[a] + r + 1);
        if (lo > 0.0) {
            bound = min(bound, at[a] - lo);
        }
        if (uint(c[a] + r + 1) < p.dims_count[a]) {
            bound = min(bound, hi - at[a]);
        }
    }
    float d = max(bound, 0.0) * p.origin_cell.w * (1.0 - 1e-5);
    return bound >= FLT_MAX ? FLT_MAX : d * d;
}

bool resolved(vec3 q, ivec3 c, int r) {
    return found == K && (covers_all(c, r) || best_d[K - 1u] <= inner_bound2(q, c, r));
}

// One Jacobi rotation annihilating m[i][j], accumulated into the eigenvectors' columns v.
void rotate(inout mat3 m, inout mat3 v, int i, int j) {
    if (m[i][j] == 0.0) {
        return;
    }
    float theta = (m[j][j] - m[i][i]) / (2.0 * m[i][j]);
    float t = (theta >= 0.0 ? 1.0 : -1.0) / (abs(theta) + sqrt(theta * theta + 1.0));
    float c = inversesqrt(t * t + 1.0);
    float s = t * c;
    mat3 g = mat3(1.0);
    g[i][i] = c;
    g[j][j] = c;
    // Column i row j: -s; column j row i: s (src/scene/preprocess.rs symmetric_eigen3).
    g[i][j] = -s;
    g[j][i] = s;
    m = transpose(g) * m * g;
    v = v * g;
}

// The PCA normal of `q` and its neighbours, or the zero vector where they span no plane
// direction (a line, one repeated point).
vec3 pca_normal(vec3 q) {
    vec3 mean = vec3(0.0);
    for (uint j = 0u; j < K; ++j) {
        mean += sorted[best_s[j]].xyz - q;
    }
    mean /= float(K + 1u);
    mat3 m = outerProduct(mean, mean);
    for (uint j = 0u; j < K; ++j) {
        vec3 e = sorted[best_s[j]].xyz - q - mean;
        m += outerProduct(e, e);
    }
    float trace = m[0][0] + m[1][1] + m[2][2];
    if (!(trace > 0.0 && trace <= FLT_MAX)) {
        return vec3(0.0);
    }
    m /= trace;
    mat3 v = mat3(1.0);
    for (int sweep = 0; sweep < 12; ++sweep) {
        float off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        if (off <= 1e-14) {
            break;
        }
        rotate(m, v, 0, 1);
        rotate(m, v, 0, 2);
        rotate(m, v, 1, 2);
    }
    vec3 l = vec3(m[0][0], m[1][1], m[2][2]);
    int low = l.x <= l.y ? (l.x <= l.z ? 0 : 2) : (l.y <= l.z ? 1 : 2);
    float high = max(l.x, max(l.y, l.z));
    float mid = l.x + l.y + l.z - high - l[low];
    // Float precision: spread in a second direction above 1e-6 of the first (the CPU's
    // double solve uses 1e-12).
    if (!(mid > high * 1e-6 && high > 0.0)) {
        return vec3(0.0);
    }
    return normalize(v[low]);
}

// Towards the sensor when the file recorded one, otherwise away from the centroid.
vec3 reference_direction(vec3 q) {
    return p.sensor.w > 0.5 ? p.sensor.xyz - q : q - p.mean.xyz;
}

// The unit direction of `d`, or zero where it has none.
vec3 direction(vec3 d) {
    float len2 = dot(d, d);
    return len2 > 0.0 && len2 <= FLT_MAX ? d * inversesqrt(len2) : vec3(0.0);
}

vec3 oriented_normal(vec3 q) {
    vec3 n = pca_normal(q);
    vec3 ref = reference_direction(q);
    if (n != vec3(0.0)) {
        return dot(n, ref) < 0.0 ? -n : n;
    }
    vec3 d = direction(ref);
    if (d == vec3(0.0)) {
        d = direction(q - p.mean.xyz);
    }
    return d == vec3(0.0) ? vec3(0.0, 0.0, 1.0) : d;
}

void main() {
    uint s = thread_index();
    if (s >= p.dims_count.w) {
        return;
    }
    vec4 point = sorted[s];
    vec3 q = point.xyz;
    uint i = floatBitsToUint(point.w);
    for (uint j = 0u; j < KNN_GRAPH_K; ++j) {
        graph[i * KNN_GRAPH_K + j] = NO_NEIGHBOUR;
    }
    if (!finite3(q)) {
        result[i] = vec4(0.0, 0.0, 1.0, -1.0);
        return;
    }
    ivec3 c = cell_of(q);
    search(q, s, c, 1);
    if (!resolved(q, c, 1)) {
        search(q, s, c, 2);
        if (!resolved(q, c, 2)) {
            result[i] = vec4(0.0, 0.0, 1.0, -1.0);
            return;
        }
    }
    result[i] = vec4(oriented_normal(q), best_d[K - 1u]);
    for (uint j = 0u; j < min(found, KNN_GRAPH_K); ++j) {
        graph[i * KNN_GRAPH_K + j] = floatBitsToUint(sorted[best_s[j]].w);
    }
}

#version 460
// Synthesis (000 4.2.2), one pass per level, top-down: texel q of level `pyr.level` keeps its
// value unless it is empty or its depth interval lies behind the texel directly above it
// (an occluded surface seen through a gap); then it is rebuilt from the (up to) four nearest
// texels of the level above whose ellipses cover q's centre (point-in-ellipse through their
// displacement vectors, 000 Fig. 4.6) and whose depth intervals overlap the front-most of
// those, weighted by a Gaussian of the elliptical distance to each centre,
// exp(-falloff d^2); an empty texel in an enclosed gap that none covers is filled from their
// ellipses grown by PYRAMID_FILL_REACH texels. Nothing covers it: an empty texel stays empty,
// an occluded one keeps its value (a deviation: on slanted surfaces, where neighbouring depth
// intervals of +-radius stop overlapping, the thesis' rule emptied valid texels no ellipse
// could refill).
#include "images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

// The parents of level `level` + 1 among the four nearest to texel `q` of `level` (centre `x`)
// whose ellipses, axes grown by `grow` level-0 pixels, cover `x`: their count, attributes,
// centres and squared elliptical distances, the front-most of them, in `valid` how many of
// the four are inside the level and not empty and in `filled` how many of those were filled
// across a gap (they cover only when `gap`).
int gather(ivec2 q, vec2 x, uint level, float grow, bool gap, out Texel cand[4],
           out vec2 centre[4], out float dist2[4], out int front, out int valid,
           out int filled) {
    ivec2 parent_size = imageSize(parent_a);
    // The four parents whose centres are nearest to q's: (q - 1) / 2 rounded down, and + 1.
    ivec2 base = (q - 1) >> 1;
    int n = 0;
    front = -1;
    valid = 0;
    filled = 0;
    for (int k = 0; k < 4; ++k) {
        ivec2 pq = base + ivec2(k & 1, k >> 1);
        if (any(lessThan(pq, ivec2(0))) || any(greaterThanEqual(pq, parent_size))) {
            continue;
        }
        Texel t = load_parent(pq);
        if (t.depth == 0.0) {
            continue;
        }
        ++valid;
        // A parent filled across a gap reaches only texels of an enclosed gap, never past a
        // silhouette.
        if (t.radius < 0.0) {
            ++filled;
            if (!gap) {
                continue;
            }
        }
        vec2 c = pixel_centre(pq, level + 1u) + t.disp;
        float d2 = ellipse_distance2_grown(t, c, x, grow);
        if (d2 > 1.0) {
            continue;
        }
        cand[n] = t;
        centre[n] = c;
        dist2[n] = d2;
        if (front < 0 || t.depth < cand[front].depth) {
            front = n;
        }
        ++n;
    }
    return n;
}

// Whether texel `q` of the level (as the analysis left it) has a valid texel within
// PYRAMID_FILL_SPAN texels in each of the four axis directions: a gap enclosed by the surface,
// not the background beyond a silhouette or beside a thin line. Texels this pass filled carry
// a negative half range and do not count, so the single-image layout, which updates the level
// in place, decides as the ping-pong layout does whatever the order of the invocations.
bool enclosed(ivec2 q) {
    ivec2 size = imageSize(level_b);
    for (int d = 0; d < 4; ++d) {
        ivec2 step = d < 2 ? ivec2(d == 0 ? 1 : -1, 0) : ivec2(0, d == 2 ? 1 : -1);
        bool found = false;
        for (int k = 1; k <= PYRAMID_FILL_SPAN && !found; ++k) {
            ivec2 p = q + step * k;
            if (any(lessThan(p, ivec2(0))) || any(greaterThanEqual(p, size))) {
                break;
            }
            vec2 b = imageLoad(level_b, p).xy;
            found = b.x > 0.0 && b.y >= 0.0;
        }
        if (!found) {
            return false;
        }
    }
    return true;
}

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(out_a);
    if (any(greaterThanEqual(q, size))) {
        return;
    }
    ivec2 parent_size = imageSize(parent_a);
    uint level = pyr.level;
    Texel own = load_level(q);
    Texel above = load_parent(min(q / 2, parent_size - 1));
    bool occluded =
        above.depth > 0.0 && own.depth - own.half_range > above.depth + abs(above.half_range);
    if (own.depth > 0.0 && !occluded) {
        store_out(q, own);
        return;
    }
    vec2 x = pixel_centre(q, level);
    Texel cand[4];
    vec2 centre[4];
    float dist2[4];
    int front;
    int valid;
    float grow = 0.0;
    int filled;
    int n = gather(q, x, level, grow, false, cand, centre, dist2, front, valid, filled);
    // Whether the texel lies in an enclosed gap matters only when a parent filled across a gap
    // is near or all four parents are valid and none covers it: only then the neighbours are
    // read (not for the background, whose parents are empty).
    bool gap = false;
    if (!occluded && level < PYRAMID_FILL_LEVELS && (filled > 0 || (n == 0 && valid == 4))) {
        gap = enclosed(q);
        if (gap && filled > 0) {
            n = gather(q, x, level, grow, true, cand, centre, dist2, front, valid, filled);
        }
    }
    if (n == 0 && gap && valid == 4) {
        // Deviation: an empty texel whose four nearest parents are all valid and that has
        // valid texels on all four sides lies in a gap enclosed by the surface (a pixel no
        // point projected to, or whose point was culled) that ellipses smaller than the
        // texel spacing leave open. The parents' ellipses are grown by PYRAMID_FILL_REACH
        // texels of this level (convolved with a disc of that radius, like EWA's prefilter)
        // to reach it, and the filled texel keeps the grown radius, negated: on the levels
        // below it covers only texels of enclosed gaps. Beyond a silhouette one side is
        // empty, so the silhouette does not grow.
        grow = PYRAMID_FILL_REACH * float(1u << level);
        n = gather(q, x, level, grow, true, cand, centre, dist2, front, valid, filled);
    }
    if (n == 0) {
        // Deviation: an "occluded" texel no parent ellipse covers keeps its value (nothing
        // in front reaches it; the thesis would leave a hole).
        store_out(q, occluded ? own : empty_texel());
        return;
    }
    Blend blend = blend_empty();
    for (int k = 0; k < n; ++k) {
        if (overlaps(cand[k], cand[front])) {
            blend_add(blend, cand[k], centre[k], exp(-pyr.falloff * dist2[k]));
        }
    }
    Texel t = blend_finish(blend, cand[front], x);
    // A texel filled across a gap keeps the grown ellipse, so that it reaches the gap's texels
    // on the levels below, marked by its sign.
    if (grow > 0.0) {
        t.radius = -length(vec2(t.radius, grow));
    }
    if (!occluded) {
        t.half_range = -t.half_range;
    }
    store_out(q, t);
}

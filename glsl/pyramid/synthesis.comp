#version 460
// Synthesis (000 4.2.2), one pass per level, top-down: texel q of level `pyr.level` keeps its
// value unless it is empty or its depth interval lies behind the texel directly above it
// (an occluded surface seen through a gap); then it is rebuilt from the (up to) four nearest
// texels of the level above whose ellipses cover q's centre (point-in-ellipse through their
// displacement vectors, 000 Fig. 4.6) and whose depth intervals overlap the front-most of
// those, weighted by a Gaussian of the elliptical distance to each centre,
// exp(-falloff d^2). Nothing covers it: an empty texel stays empty, an occluded one keeps its
// value (a deviation: on slanted surfaces, where neighbouring depth intervals of +-radius stop
// overlapping, the thesis' rule emptied valid texels no ellipse could refill).
#include "images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

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
    bool occluded = above.depth > 0.0 && own.depth - own.half_range > above.depth + above.half_range;
    if (own.depth > 0.0 && !occluded) {
        store_out(q, own);
        return;
    }
    // The four parents whose centres are nearest to q's: (q - 1) / 2 rounded down, and + 1.
    ivec2 base = (q - 1) >> 1;
    vec2 x = pixel_centre(q, level);
    Texel cand[4];
    vec2 centre[4];
    float dist2[4];
    int n = 0;
    int front = -1;
    for (int k = 0; k < 4; ++k) {
        ivec2 pq = base + ivec2(k & 1, k >> 1);
        if (any(lessThan(pq, ivec2(0))) || any(greaterThanEqual(pq, parent_size))) {
            continue;
        }
        Texel t = load_parent(pq);
        if (t.depth == 0.0) {
            continue;
        }
        vec2 c = pixel_centre(pq, level + 1u) + t.disp;
        float d2 = ellipse_distance2(t, c, x);
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
    store_out(q, t);
}

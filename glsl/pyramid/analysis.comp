#version 460
// Analysis (000 4.2.2), one pass per level, bottom-up: texel p of level `pyr.level` is the
// average of the valid texels among its children in the level below (2p .. 2p + 1, and the
// last row or column of an odd-sized level too) whose depth intervals overlap the front-most
// child's; the mean of their ellipse centres becomes its displacement vector. No valid child:
// empty.
#include "images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(out_a);
    if (any(greaterThanEqual(p, size))) {
        return;
    }
    ivec2 child_size = imageSize(level_a);
    ivec2 lo = 2 * p;
    ivec2 hi = min(mix(lo + 1, child_size - 1, equal(p, size - 1)), child_size - 1);
    uint child_level = pyr.level - 1u;

    // The front-most valid child is the reference of the occlusion test.
    Texel front = empty_texel();
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            Texel t = load_level(ivec2(x, y));
            if (t.depth > 0.0 && (front.depth == 0.0 || t.depth < front.depth)) {
                front = t;
            }
        }
    }
    if (front.depth == 0.0) {
        store_out(p, empty_texel());
        return;
    }
    Blend blend = blend_empty();
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            ivec2 c = ivec2(x, y);
            Texel t = load_level(c);
            if (t.depth == 0.0 || !overlaps(t, front)) {
                continue;
            }
            blend_add(blend, t, pixel_centre(c, child_level) + t.disp, 1.0);
        }
    }
    Texel parent = blend_finish(blend, front, pixel_centre(p, pyr.level));
    store_out(p, parent);
}

#version 460
// Analysis of the pyramid with search kernels (000 6.1), one pass per level, bottom-up: a
// child travels on while its kernel level lies above its own level; texel p of level
// `pyr.level` merges its travelling children (2p .. 2p + 1, and the last row or column of an
// odd-sized level too) as ch. 4's analysis does: the average of those whose depth intervals
// overlap the front-most one's, the mean of their ellipse centres as displacement vector.
// Children stored in their own level (kernel level at most theirs) stay there, so each splat
// is stored in exactly one level; whether a texel is stored in its level or only passing
// through follows from its radius (kernel_level), read back by the interpolation.
#include "kernel.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

bool travels(Texel t, uint child_level) {
    return t.depth > 0.0 && kernel_level(t.radius) > child_level;
}

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

    Texel front = empty_texel();
    for (int y = lo.y; y <= hi.y; ++y) {
        for (int x = lo.x; x <= hi.x; ++x) {
            Texel t = load_level(ivec2(x, y));
            if (travels(t, child_level) && (front.depth == 0.0 || t.depth < front.depth)) {
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
            if (!travels(t, child_level) || !overlaps(t, front)) {
                continue;
            }
            blend_add(blend, t, pixel_centre(c, child_level) + t.disp, 1.0);
        }
    }
    store_out(p, blend_finish(blend, front, pixel_centre(p, pyr.level)));
}

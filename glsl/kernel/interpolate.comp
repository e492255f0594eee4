#version 460
// Interpolation of the pyramid with search kernels (000 6.2), one pass per level searched,
// level 0 first: every level-0 pixel visits the KERNEL x KERNEL texels around its own texel
// of level `pyr.level` (clamped to the level's last row and column); a texel stored in that
// level (not one passing through: kernel_level) whose ellipse contains the pixel centre adds
// with the linear weight w = 1 - d (eq. 6.2), d the elliptical distance to the ellipse centre
// (texel centre plus displacement; 1 on the rim), to the pixel's accumulators (one more read
// per level, as in the thesis, here only where something is added). The first pass starts
// them empty.
#include "kernel_accum.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = ivec2(frame.u.viewport.xy);
    if (any(greaterThanEqual(px, size))) {
        return;
    }
    uint level = pyr.level;
    vec2 x = pixel_centre(px, 0u);
    ivec2 level_size = imageSize(level_a);
    ivec2 q = min(px >> level, level_size - 1);
    int reach = int(KERNEL - 1u) / 2;
    // The sums are read on the first contribution and written back only when something
    // was added (the first pass writes every pixel); an empty texel costs one load.
    Accum s = accum_empty();
    bool touched = level == 0u;
    for (int dy = -reach; dy <= reach; ++dy) {
        for (int dx = -reach; dx <= reach; ++dx) {
            ivec2 c = q + ivec2(dx, dy);
            if (any(lessThan(c, ivec2(0))) || any(greaterThanEqual(c, level_size))) {
                continue;
            }
            vec4 b = imageLoad(level_b, c);
            if (b.x == 0.0) {
                continue;
            }
            vec4 a = imageLoad(level_a, c);
            if (kernel_level(a.w) > level) {
                continue;
            }
            Texel t = unpack_texel(a, b, COLOR ? imageLoad(level_c, c) : vec4(0.0));
            float d2 = ellipse_distance2(t, pixel_centre(c, level) + t.disp, x);
            if (d2 < 1.0) {
                if (!touched) {
                    s = accum_load(px);
                    touched = true;
                }
                accum_add(s, t, 1.0 - sqrt(d2));
            }
        }
    }
    if (touched) {
        accum_store(px, s);
    }
}

// The pyramid with search kernels (000 ch. 6): the kernel size and the level each splat is
// stored in. Texels are the pyramid's (pyramid.glsl, images.glsl); `pyr.level_count` holds
// the levels searched (the pyramid's levels up to the first one the kernel below covers).
#ifndef SURFEL_PYRAMID_KERNEL_GLSL
#define SURFEL_PYRAMID_KERNEL_GLSL
#include "../pyramid/images.glsl"

// The kernel is KERNEL x KERNEL texels (3, 5 or 7).
layout(constant_id = PYRAMID_SPEC_KERNEL) const uint KERNEL = 3u;

// The level a splat of projected radius `radius` (level-0 pixels) is stored in: the least l
// with KERNEL 2^l >= 2 radius (eq. 6.1 with D the diameter; see kernel_reference.rs), at most
// the top level searched. An integer loop keeps the powers of two exact.
uint kernel_level(float radius) {
    uint top = pyr.level_count - 1u;
    uint level = 0u;
    while (level < top && float(KERNEL << level) < 2.0 * radius) {
        ++level;
    }
    return level;
}
#endif

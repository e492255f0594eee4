#version 460
// Pyramid test: writes level 0 of the pyramid's groups from a buffer of texels (A, B and C as
// three vec4 per pixel, row-major).
#include "../pyramid/images.glsl"

layout(local_size_x = PYRAMID_GROUP, local_size_y = PYRAMID_GROUP) in;

layout(set = 0, binding = BINDING_INPUT0, std430) readonly buffer Texels { vec4 texels[]; };

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(out_a);
    if (any(greaterThanEqual(q, size))) {
        return;
    }
    uint k = 3u * uint(q.y * size.x + q.x);
    imageStore(out_a, q, texels[k]);
    imageStore(out_b, q, texels[k + 1u]);
    if (COLOR) {
        imageStore(out_c, q, texels[k + 2u]);
    }
}

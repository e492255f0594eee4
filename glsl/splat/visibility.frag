#version 460
// Visibility pass of the blended shadings (002 section 5.3.2): depth only, nearest surface
// point wins; also writes the linear depth target the normalization pass keeps.
#include "fragment.glsl"

layout(location = 0) out float o_depth;

void main() {
    SplatHit hit = splat_fragment();
    gl_FragDepth = zbuffer_depth(hit.q);
    o_depth = -hit.q.z;
}

#version 460
// Viewer overlay: a glyph's coverage from the R8 atlas (1 texel = 1 pixel, no filtering) or a
// solid panel, in the instance's color; the pipeline blends it over the frame's color.
#include "common.glsl"

layout(std430, set = 0, binding = BINDING_OVERLAY_GLYPHS) readonly buffer Glyphs {
    GpuGlyph glyphs[];
};

layout(std430, set = 0, binding = BINDING_OVERLAY_ATLAS) readonly buffer Atlas {
    uint atlas[];
};

layout(location = 0) flat in uint v_glyph;

layout(location = 0) out vec4 o_color;

void main() {
    GpuGlyph g = glyphs[v_glyph];
    vec4 color = unpackUnorm4x8(g.color);
    float coverage = 1.0;
    if ((g.flags & OVERLAY_SOLID) == 0u) {
        uvec2 local = uvec2(gl_FragCoord.xy - g.rect.xy);
        uint texel = (g.atlas_y + local.y) * OVERLAY_ATLAS_WIDTH + g.atlas_x + local.x;
        coverage = float((atlas[texel >> 2] >> ((texel & 3u) * 8u)) & 0xffu) / 255.0;
    }
    o_color = vec4(color.rgb, color.a * coverage);
}

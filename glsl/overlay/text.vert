#version 460
// Viewer overlay: one instanced quad per glyph or panel, placed in framebuffer pixels.
#include "common.glsl"

layout(std430, set = 0, binding = BINDING_OVERLAY_GLYPHS) readonly buffer Glyphs {
    GpuGlyph glyphs[];
};

layout(location = 0) flat out uint v_glyph;

void main() {
    // Two triangles: corners (0,0) (1,0) (0,1) / (0,1) (1,0) (1,1).
    const vec2 corners[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(0, 1), vec2(0, 1), vec2(1, 0),
                                   vec2(1, 1));
    GpuGlyph g = glyphs[gl_InstanceIndex];
    vec2 pixel = mix(g.rect.xy, g.rect.zw, corners[gl_VertexIndex]);
    gl_Position = vec4(pixel * frame.u.viewport.zw * 2.0 - 1.0, 0.0, 1.0);
    v_glyph = uint(gl_InstanceIndex);
}

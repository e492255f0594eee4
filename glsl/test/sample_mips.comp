#version 460
// Graph test: samples a mip-range view at lod 0, 1 and 0.5 (between its two levels).

layout(local_size_x = 1) in;

layout(set = 0, binding = 0) uniform sampler2D levels;

layout(set = 0, binding = 1, std430) writeonly buffer Texels {
    vec4 texels[];
};

void main() {
    texels[0] = textureLod(levels, vec2(0.5), 0.0);
    texels[1] = textureLod(levels, vec2(0.5), 1.0);
    texels[2] = textureLod(levels, vec2(0.5), 0.5);
}

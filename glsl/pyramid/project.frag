#version 460
// Writes a projected point's texel into level 0's three groups (see project.vert).
layout(location = 0) flat in vec4 v_a;
layout(location = 1) flat in vec4 v_b;
layout(location = 2) flat in vec4 v_c;

layout(location = 0) out vec4 out_a;
layout(location = 1) out vec4 out_b;
layout(location = 2) out vec4 out_c;

void main() {
    out_a = v_a;
    out_b = v_b;
    out_c = v_c;
}

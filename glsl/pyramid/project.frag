#version 460
// Writes a texel of level 0 into its three groups: a projected point's (project.vert) or a
// triangle fragment's, interpolated across the face (triangles.vert). The primitive id (C.a)
// is the same at every vertex of a primitive.
layout(location = 0) in vec4 v_a;
layout(location = 1) in vec4 v_b;
layout(location = 2) in vec4 v_c;

layout(location = 0) out vec4 out_a;
layout(location = 1) out vec4 out_b;
layout(location = 2) out vec4 out_c;

void main() {
    out_a = vec4(normalize(v_a.xyz), v_a.w);
    out_b = v_b;
    out_c = v_c;
}

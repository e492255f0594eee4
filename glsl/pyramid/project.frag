#version 460
// Writes a texel of level 0 into its three groups: a projected point's (project.vert) or a
// triangle fragment's, interpolated across the face (triangles.vert). The primitive id (C.a)
// is not interpolated (`flat`): perspective-correct interpolation of a value equal at every
// vertex may return it less an ulp, which would truncate to the id below (a triangle's to a
// tube's).
layout(location = 0) in vec4 v_a;
layout(location = 1) in vec4 v_b;
layout(location = 2) in vec3 v_c;
layout(location = 3) flat in uint v_primitive;

layout(location = 0) out vec4 out_a;
layout(location = 1) out vec4 out_b;
layout(location = 2) out vec4 out_c;

void main() {
    out_a = vec4(normalize(v_a.xyz), v_a.w);
    out_b = v_b;
    out_c = vec4(v_c, float(v_primitive));
}

#version 460
// The geometry expansion (000 7.2): one vertex per patch carries the patch's index to
// lod/expand.geom (the thesis sends the representative vertex itself; here the geometry
// shader reads the patch record, with the representative, from the patch buffer).
layout(location = 0) flat out uint v_patch;

void main() {
    v_patch = uint(gl_VertexIndex);
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}

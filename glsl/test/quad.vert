#version 460
// Graph test: vertices 0..5 cover the left half of the target, 6..11 the right half.

void main() {
    const vec2 corners[6] = vec2[](
        vec2(0.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(0.0, -1.0), vec2(1.0, 1.0), vec2(0.0, 1.0));
    vec2 c = corners[gl_VertexIndex % 6];
    float left = float(gl_VertexIndex / 6) - 1.0;
    gl_Position = vec4(c.x + left, c.y, 0.0, 1.0);
}

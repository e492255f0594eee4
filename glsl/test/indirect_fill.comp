#version 460
// Graph test: every invocation i of an indirect dispatch writes i * SCALE + 1.

layout(local_size_x = 4) in;

layout(constant_id = 0) const uint SCALE = 1;

layout(set = 0, binding = 0, std430) buffer Values {
    uint values[];
};

void main() {
    uint i = gl_GlobalInvocationID.x;
    values[i] = i * SCALE + 1;
}

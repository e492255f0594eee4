#version 460
// Graph test: turns a uniform group count into dispatch arguments at uints 4..7.

layout(local_size_x = 1) in;

layout(set = 0, binding = 0) uniform Params {
    uint groups;
} params;

layout(set = 0, binding = 1, std430) writeonly buffer Args {
    uint args[];
};

void main() {
    args[4] = params.groups;
    args[5] = 1;
    args[6] = 1;
}

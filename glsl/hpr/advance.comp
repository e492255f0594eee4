#version 460
// After an adaptive propagation round (003 4.3.1), one thread: count the round if it changed
// an extreme, else empty the indirect dispatch of every later round (they are recorded, up
// to the cap, but run no workgroups).
#define HPR_WRITES_STATE
#include "hpr.glsl"

layout(local_size_x = 1) in;

void main() {
    if (h.changed != 0u) {
        h.rounds += 1u;
        h.changed = 0u;
    } else {
        h.groups_x = 0u;
    }
}

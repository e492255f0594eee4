// The mesh path's task payload (000 7.2 with a task shader in place of the geometry shader):
// per launched mesh workgroup, the first vertex of the chosen level and its count | level << 24.
#ifndef SURFEL_LOD_PAYLOAD_GLSL
#define SURFEL_LOD_PAYLOAD_GLSL
struct LodPayload {
    uint first[LOD_TASK_GROUP];
    uint count_level[LOD_TASK_GROUP];
};
taskPayloadSharedEXT LodPayload payload;
#endif

// Whether stream index i holds a point this frame. Batch b covers indices b * BATCH_POINTS on
// (in a loaded cloud and in a streamed cloud's pool alike) and holds `count` points: a
// streamed pool has empty and partly filled batch slots, whose indices a draw of every
// index must skip.
#ifndef SURFEL_LIVE_GLSL
#define SURFEL_LIVE_GLSL
#include "common.glsl"

layout(std430, set = 0, binding = BINDING_BATCHES) readonly buffer LiveBatches {
    GpuBatch live_batches[];
};

bool stream_live(uint i) {
    return i % BATCH_POINTS < live_batches[i / BATCH_POINTS].count;
}
#endif

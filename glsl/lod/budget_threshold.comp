#version 460
// The point budget's second pass, one workgroup: the refinements are admitted in
// order of decreasing projected error until the budget is full. With S_k the samples of bins
// k and above, drawing with threshold edge(k) (the smallest error bin k holds) projects at
// most budget_base + S_k samples; the threshold becomes ε when everything fits (k = 0), the
// smallest fitting edge otherwise, or infinity (every patch at its coarsest level) when no
// edge fits. `ObjectTexture::budget_threshold` is the CPU reference.
#include "lod.glsl"

layout(local_size_x = LOD_BUDGET_BINS) in;

layout(std430, set = 0, binding = BINDING_LOD_COUNTERS) buffer Counters {
    LOD_COUNTERS_MEMBERS
};

layout(push_constant) uniform Push { LodParams pc; };

shared uint suffix[LOD_BUDGET_BINS];
shared uint first_fit;

void main() {
    uint i = gl_LocalInvocationIndex;
    suffix[i] = bins[i];
    if (i == 0u) {
        first_fit = LOD_BUDGET_BINS;
    }
    barrier();
    // Inclusive suffix sums (Hillis-Steele).
    for (uint d = 1u; d < LOD_BUDGET_BINS; d <<= 1u) {
        uint add = i + d < LOD_BUDGET_BINS ? suffix[i + d] : 0u;
        barrier();
        suffix[i] += add;
        barrier();
    }
    // The sums fall with i, so the fitting bins are a suffix of the bins.
    if (budget_base + suffix[i] <= pc.budget) {
        atomicMin(first_fit, i);
    }
    barrier();
    if (i == 0u) {
        uint k = first_fit;
        threshold = k == 0u
            ? pc.epsilon
            : k == LOD_BUDGET_BINS ? uintBitsToFloat(0x7f800000u)
                                   : uintBitsToFloat((k + LOD_BUDGET_BIN_BASE) << 20);
    }
}

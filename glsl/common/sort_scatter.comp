#version 460
// Radix sort, pass (c) of each digit: every tile moves its (key, value) pairs to
// offset[digit, tile] + rank, where offset is the scanned histogram and rank counts the
// tile's earlier elements with the same digit, so the sort is stable.
//
// The tile is processed in SORT_ITEMS chunks of SORT_GROUP elements. Within a chunk, a
// subgroup finds the peers sharing an element's digit with one ballot per digit bit (uvec4
// ballots: any subgroup size up to 128); the element's rank in its subgroup is the number of
// peers on lower lanes. The first peer stores the subgroup's count of that digit in shared
// memory; a serial pass per digit over the subgroups, in order, turns the counts into output
// positions and advances the tile's running offset of the digit for the next chunk.
//
// Element order within a chunk follows (gl_SubgroupID, gl_SubgroupInvocationID), so ranks do
// not depend on how the implementation maps local invocations to subgroups.
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "sort.glsl"

layout(local_size_x = SORT_GROUP) in;

// Subgroups per workgroup: SORT_GROUP / the device's subgroup size.
layout(constant_id = SORT_SPEC_SUBGROUPS) const uint SUBGROUPS = 1;

layout(std430, set = 0, binding = BINDING_SORT_KEYS) readonly buffer Keys { uint keys[]; };
layout(std430, set = 0, binding = BINDING_SORT_VALUES) readonly buffer Values {
    uint64_t values[];
};
layout(std430, set = 0, binding = BINDING_SORT_KEYS_OUT) writeonly buffer KeysOut {
    uint keys_out[];
};
layout(std430, set = 0, binding = BINDING_SORT_VALUES_OUT) writeonly buffer ValuesOut {
    uint64_t values_out[];
};
layout(std430, set = 0, binding = BINDING_SORT_HIST) readonly buffer Hist { uint hist[]; };

// The tile's next output position per digit.
shared uint next[SORT_RADIX];
// Per subgroup and digit: the chunk's count, then the subgroup's first output position.
shared uint offsets[SUBGROUPS * SORT_RADIX];

void main() {
    uint tile = group_index();
    if (tile >= pc.tiles) {
        return;
    }
    uint t = gl_LocalInvocationIndex;
    for (uint d = t; d < SORT_RADIX; d += SORT_GROUP) {
        next[d] = hist[d * pc.tiles + tile];
    }
    for (uint j = t; j < SUBGROUPS * SORT_RADIX; j += SORT_GROUP) {
        offsets[j] = 0;
    }
    barrier();
    uint subgroup = gl_SubgroupID;
    uint lane = subgroup * gl_SubgroupSize + gl_SubgroupInvocationID;
    uint start = tile * SORT_GROUP * SORT_ITEMS;
    for (uint k = 0; k < SORT_ITEMS; ++k) {
        uint i = start + k * SORT_GROUP + lane;
        bool valid = i < pc.count;
        uint key = valid ? keys[i] : 0;
        uint64_t value = valid ? values[i] : 0ul;
        uint digit = digit_of(key);
        // Lanes holding a valid element with the same digit (this lane included).
        uvec4 peers = subgroupBallot(valid);
        for (uint b = 0; b < SORT_DIGIT_BITS; ++b) {
            bool set = ((digit >> b) & 1u) != 0;
            uvec4 vote = subgroupBallot(set);
            peers &= set ? vote : ~vote;
        }
        uint rank = subgroupBallotExclusiveBitCount(peers);
        if (valid && rank == 0) {
            offsets[subgroup * SORT_RADIX + digit] = subgroupBallotBitCount(peers);
        }
        barrier();
        for (uint d = t; d < SORT_RADIX; d += SORT_GROUP) {
            uint run = next[d];
            for (uint s = 0; s < gl_NumSubgroups; ++s) {
                uint c = offsets[s * SORT_RADIX + d];
                offsets[s * SORT_RADIX + d] = run;
                run += c;
            }
            next[d] = run;
        }
        barrier();
        if (valid) {
            uint dst = offsets[subgroup * SORT_RADIX + digit] + rank;
            keys_out[dst] = key;
            values_out[dst] = value;
        }
        barrier();
        for (uint j = t; j < SUBGROUPS * SORT_RADIX; j += SORT_GROUP) {
            offsets[j] = 0;
        }
        barrier();
    }
}

// The workgroup-wide exclusive prefix sum of the radix sort's scan passes (reduce, block sums,
// downsweep): Hillis-Steele over one value per thread in shared memory, log2(SCAN_GROUP)
// steps. Every thread first adds its SCAN_ITEMS consecutive entries serially.
#include "sort.glsl"

layout(local_size_x = SCAN_GROUP) in;

#define SCAN_BLOCK (SCAN_GROUP * SCAN_ITEMS)

shared uint scan_partial[SCAN_GROUP];

// The sum of `v` over the threads before this one; `total` is the sum over all threads.
// Every thread of the workgroup must call it (it synchronizes the workgroup).
uint scan_exclusive(uint v, out uint total) {
    uint t = gl_LocalInvocationIndex;
    scan_partial[t] = v;
    barrier();
    for (uint step = 1; step < SCAN_GROUP; step <<= 1) {
        uint add = t >= step ? scan_partial[t - step] : 0;
        barrier();
        scan_partial[t] += add;
        barrier();
    }
    total = scan_partial[SCAN_GROUP - 1];
    uint inclusive = scan_partial[t];
    // The next call overwrites the array only after every thread read it.
    barrier();
    return inclusive - v;
}

//! The pyramid with search kernels (000 ch. 6, src/methods/kernel).

use super::StructSpec;

pub const CONSTANTS: &[(&str, u32)] = &[
    // The pyramid with search kernels (000 ch. 6, src/methods/pyramid/kernel.rs): the kernel
    // size k (3, 5 or 7) as a specialization constant, and the per-pixel accumulators of the
    // interpolation passes at three consecutive bindings (RGBA32F: sum of w n and of w; sums of
    // w depth and w radius, the front-most contribution's depth and half range; sum of w albedo).
    ("PYRAMID_SPEC_KERNEL", 4),
    ("BINDING_KERNEL_ACCUM", 16),
];

pub const STRUCTS: &[StructSpec] = &[];

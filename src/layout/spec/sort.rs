//! The GPU radix sort and segmented maximum (src/methods/common/sort.rs).

use super::StructSpec;

pub const CONSTANTS: &[(&str, u32)] = &[
    // GPU radix sort and segmented maximum (src/methods/hpr/sort.rs): bindings of the keys and
    // values read and written, the digit histogram and the scan's block sums.
    ("BINDING_SORT_KEYS", 32),
    ("BINDING_SORT_VALUES", 33),
    ("BINDING_SORT_KEYS_OUT", 34),
    ("BINDING_SORT_VALUES_OUT", 35),
    ("BINDING_SORT_HIST", 36),
    ("BINDING_SORT_SUMS", 37),
    // Bits per digit and digits (histogram bins) per pass.
    ("SORT_DIGIT_BITS", 8),
    ("SORT_RADIX", 256),
    // Count and scatter: SORT_GROUP threads, SORT_ITEMS elements each per tile.
    ("SORT_GROUP", 128),
    ("SORT_ITEMS", 8),
    // Scan: SCAN_GROUP threads, SCAN_ITEMS consecutive entries each per block.
    ("SCAN_GROUP", 256),
    ("SCAN_ITEMS", 4),
    // Segmented maximum: one element per thread, SEGMAX_GROUP elements per tile.
    ("SEGMAX_GROUP", 256),
    // Specialization constant id of the scatter's subgroups per workgroup.
    ("SORT_SPEC_SUBGROUPS", 0),
];

pub const STRUCTS: &[StructSpec] = &[];

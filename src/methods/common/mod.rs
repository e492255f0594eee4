//! GPU building blocks several method families share: the radix sort and segmented maximum
//! (`sort`).

pub mod sort;

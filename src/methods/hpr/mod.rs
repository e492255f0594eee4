//! GPU building blocks of hidden point removal (003): radix sort and segmented maximum.

pub mod sort;

//! surfel: a Vulkan-native point-cloud renderer.

pub mod gpu;
pub mod graph;

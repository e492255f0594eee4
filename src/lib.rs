//! surfel: a Vulkan-native point-cloud renderer.

pub mod gpu;
pub mod graph;
pub mod eval;
pub mod scene;
pub mod methods;
pub mod render;

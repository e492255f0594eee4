//! surfel: a Vulkan-native point-cloud renderer.

pub mod cli;
pub mod color;
pub mod copc;
pub mod eval;
pub mod frame;
pub mod gpu;
pub mod gpu_scene;
pub mod graph;
pub mod hpr;
pub mod knn_gpu;
pub mod layout;
pub mod lod;
pub mod methods;
pub mod overlay;
pub mod point_streams;
pub mod post;
pub mod render;
pub mod rng;
pub mod scene;
pub mod source;
pub mod suggest;
pub mod viewer;

//! surfel: a Vulkan-native point-cloud renderer.

pub mod app;
pub mod cli;
pub mod color;
pub mod estimate;
pub mod eval;
pub mod frame;
pub mod gpu;
pub mod graph;
pub mod hpr;
pub mod layout;
pub mod lod;
pub mod methods;
pub mod overlay;
pub mod post;
pub mod render;
pub mod rng;
pub mod scene;
pub mod source;
pub mod stream;
pub mod streams;
pub mod suggest;
pub mod upload;

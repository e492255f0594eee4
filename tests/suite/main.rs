//! The integration tests of every part but the two that install a counting global allocator
//! (`tests/bounded.rs`, `tests/frames.rs`): one crate, so the test build links once. GPU tests
//! run on a validated lavapipe context each (`common::context`).

mod bench;
mod cli;
mod color;
#[path = "../common/mod.rs"]
mod common;
mod compute;
mod estimate;
mod eval_reports;
mod ewa;
mod formats;
mod fuzz_regressions;
mod gpu_study;
mod graph;
mod graph_gpu;
mod hpr;
mod hpr_exact;
mod hpr_sort;
mod kernel;
mod layers;
mod lines;
mod loaders;
mod lod;
mod malformed;
mod orient;
mod post;
mod preprocess;
mod pyramid;
mod render_methods;
mod robustness;
mod splat;
mod stream;
mod tiles;
mod validation;
mod viewer;
mod viewer_tools;
mod vpc;

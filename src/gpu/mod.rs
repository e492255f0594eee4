//! Thin ash layer: context, frames in flight, memory, staging uploads, pipelines, timestamps,
//! swapchain.

pub mod context;
pub mod frames;
pub mod memory;
pub mod pipeline;
pub mod pipeline_cache;
pub mod profiler;
pub mod staging;
pub mod swapchain;

pub use context::{Capabilities, Context, ContextOptions};
pub use frames::FrameRing;
pub use memory::{Buffer, Image, ImageDesc};
pub use pipeline::{Binding, Blend, GeometryOutput, GraphicsDesc, Pipeline};
pub use profiler::{Profiler, SampleWindow, ScopeStats, Series};

//! Thin ash layer: context, memory, pipelines, timestamps, shared layouts, swapchain.

pub mod context;
pub mod layout;
pub mod memory;
pub mod pipeline;
pub mod pipeline_cache;
pub mod profiler;
pub mod upload;

pub use context::{Capabilities, Context, ContextOptions};
pub use memory::{Buffer, Image, ImageDesc};
pub use pipeline::{Binding, Blend, GraphicsDesc, Pipeline};
pub use profiler::{Profiler, ScopeStats};
pub mod swapchain;

//! Evaluation: metrics, sweeps, stress transforms, results, charts and reports. [`Frame`], what
//! the metrics compare, lives in [`crate::frame`] (the renderer produces it) and is re-exported.

pub mod bench;
pub mod charts;
pub mod compare;
pub mod config;
pub mod hpr;
pub mod lod;
pub mod metrics;
pub mod report;
pub mod results;
pub mod stats;
pub mod stress;
pub mod timing;

pub use crate::frame::Frame;

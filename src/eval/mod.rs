//! Evaluation: frames, metrics, sweeps, stress transforms, results, charts and reports.

pub mod bench;
pub mod charts;
pub mod config;
pub mod frame;
pub mod metrics;
pub mod report;
pub mod results;
pub mod stress;

pub use frame::Frame;

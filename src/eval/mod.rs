//! Evaluation: frames, ground truth, metrics, sweeps, charts, reports.

pub mod frame;

pub use frame::Frame;

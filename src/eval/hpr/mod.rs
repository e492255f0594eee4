//! The HPR study (`surfel hpr-study`): visible points against k (003 Fig. 5.1), precision,
//! recall and F1 of the approximation against exact HPR and of both against true visibility
//! (the mesh's depth buffer), per-pass GPU time against the number of points (sort-free and
//! sorted), the R and noise sweeps, and the partial reconstruction at 900 x 900 (003 Table
//! 5.3). `study` runs and measures the configurations, `report` writes `report.md`,
//! `results.json` and charts of what it measured, `render` holds the renders both need.

mod render;
mod report;
mod study;

pub(crate) use render::{mesh_visibility, render_once};
pub use report::write_report;
pub use study::{run, Row, StudyOptions};

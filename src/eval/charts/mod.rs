//! Charts of a sweep, each written as PNG and SVG with the device name in the caption.
//!
//! Which records feed which chart (records with a stress are only used by the stress
//! charts; the rest are the "baseline"):
//! - speed vs accuracy and per-pass times, per model and slice ([`model_slices`]: one
//!   resolution and point count; the headline slice, the largest resolution and within it the
//!   largest count, is named after the model alone, the others `MODEL_Npts_WxH`), averaged per
//!   method configuration ([`Record::label`]) over poses and light counts. The ground truth
//!   ([`Record::is_reference`]) is left off the speed-vs-accuracy axes and named in the legend
//!   with its time; the time axis is logarithmic when the times span more than
//!   [`LOG_TIME_RATIO`]. The per-pass chart stacks one segment per entry ([`pass_entry`]:
//!   the numbered passes of one step, such as the levels of a pyramid, share one), grouped by
//!   method family ([`pass_family`]);
//! - time vs points, per resolution with at least two point counts
//!   (`time_vs_points_WxH`): the baseline records at that resolution, one series per
//!   (label, model) averaged per point count, so no line joins two models;
//! - time vs resolution, per model: the baseline records at the point count with the most
//!   distinct resolutions, averaged per (label, pixels);
//! - time vs lights, per model: the baseline records at the (points, resolution) with the most
//!   distinct light counts, averaged per (label, lights) (002 ch. 6's light sweeps);
//! - time along a camera path, per model and path pose (`MODEL_path_POSE`; further slices of
//!   one pose add points, resolution and lights): each configuration's GPU time of every
//!   frame against the path's time (records with [`Record::path_times`]);
//! - metric vs stress, per model and stress kind: hole ratio (with the
//!   [`BREAK_HOLE_RATIO`](super::metrics::BREAK_HOLE_RATIO) threshold and each method's
//!   first breaking value marked, methods breaking at one point sharing a note) and PSNR.
//!
//! A chart with fewer than two data points (line charts: two distinct x values) is skipped.
//! A method configuration has the same color in every chart of one results set, and so does
//! a pass: a shade of its family's hue ([`Colors`]); a line chart over several models draws
//! each model's series with its own marker and dash. Legends sit outside the data, beside the
//! plot (below it on speed-vs-accuracy charts), and a chart whose legend needs more rows than
//! [`CHART_SIZE`] holds grows taller. An accuracy axis never spans less than its
//! [`AxisFloor`]; when all values lie closer than that, the line under the caption says so.
//!
//! This file holds the entry points, the chart trait, captions and the PNG and SVG writing;
//! `select.rs` picks the records a chart compares, `axes.rs` fits its axes, `style.rs` holds
//! colors, series styles and the font, and `legend.rs` lays out legends. Each chart kind has
//! its file: `pareto.rs` (speed vs accuracy), `stacked.rs` (per-pass times), `line.rs` (line
//! charts, with the label placement the speed-vs-accuracy chart shares) and `stress.rs` (the
//! stress charts, which are line charts).

use std::error::Error;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::results::{MetricFn, Record, Results};

mod axes;
mod legend;
mod line;
mod pareto;
mod select;
mod stacked;
mod stress;
mod style;

pub use axes::{AxisFloor, SpeedAxes, LOG_TIME_RATIO};
pub use select::{model_slices, models, reference_times, speed_accuracy};
pub use style::Colors;

use axes::compact;
use line::{time_series, LineChart, Series};
use pareto::ParetoChart;
use select::{baseline, path_slices, slice_with_most, speed_intervals};
use stacked::StackedPassChart;
use stress::write_stress_charts;
use style::register_font;

/// Pixel size of every chart, unless its legend needs a taller one.
pub const CHART_SIZE: (u32, u32) = (1024, 720);

type DrawResult = Result<(), Box<dyn Error + Send + Sync>>;

/// A chart that can draw itself on any plotters backend.
trait Chart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static;

    /// Data points drawn; charts with fewer than two are skipped.
    fn points(&self) -> usize;

    /// Pixel size: [`CHART_SIZE`], taller where the legend needs it.
    fn size(&self) -> (u32, u32) {
        CHART_SIZE
    }
}

/// The family of pass `name`: its prefix before the first `.`, the method that records it
/// (`pyramid.analysis.3` → `pyramid`, `compute-hq.resolve` → `compute-hq`).
pub fn pass_family(name: &str) -> &str {
    name.split('.').next().unwrap_or(name)
}

/// The per-pass chart's entry of pass `name`: the numbered passes of one step (the levels of
/// a pyramid, `pyramid.analysis.3`; the rounds of a propagation, `hpr.round.12`) share one,
/// named without the number; any other pass is its own.
pub fn pass_entry(name: &str) -> String {
    match name.rsplit_once('.') {
        Some((stem, n)) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => {
            stem.to_string()
        }
        _ => name.to_string(),
    }
}

/// Draws `caption` (and `note` in a smaller line under it) at the top of `root` and returns
/// the area below. A caption too wide for the chart at 22 px is set smaller (down to 14 px).
fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    caption: &str,
    note: Option<&str>,
) -> Result<DrawingArea<DB, Shift>, Box<dyn Error + Send + Sync>>
where
    DB::ErrorType: 'static,
{
    let width = root.dim_in_pixel().0.saturating_sub(16);
    let mut size = 22;
    while size > 14
        && root
            .estimate_text_size(caption, &TextStyle::from(("sans-serif", size).into_font()))?
            .0
            > width
    {
        size -= 1;
    }
    let area = root
        .margin(8, 0, 0, 0)
        .titled(caption, ("sans-serif", size))?;
    Ok(match note {
        Some(note) => area.titled(note, ("sans-serif", 16).into_font().color(&BLACK.mix(0.7)))?,
        None => area,
    })
}

/// Writes `chart` as `dir/stem.png` and `dir/stem.svg`; nothing when it has too few points.
fn write_both(chart: &impl Chart, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
    if chart.points() < 2 {
        return Ok(Vec::new());
    }
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    let fail =
        |path: &Path, e: Box<dyn Error + Send + Sync>| anyhow!("drawing {}: {e}", path.display());
    let size = chart.size();
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        chart.draw(&root).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.into()))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        chart.draw(&root).map_err(|e| fail(&svg, e))?;
        root.present().map_err(|e| fail(&svg, e.into()))?;
    }
    Ok(vec![png, svg])
}

/// File-name-safe version of a model or stress name.
fn slug(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Writes a line chart of `series` (name, points) as `dir/stem.png` and `.svg` (for studies
/// outside the benchmark's results sets, e.g. the HPR report); nothing for fewer than two
/// distinct x values. A PSNR or SSIM y axis ([`AxisFloor::of_desc`]) keeps its floor.
pub fn write_line_chart(
    dir: &Path,
    stem: &str,
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    log_x: bool,
    series: Vec<(String, Vec<(f64, f64)>)>,
) -> Result<Vec<PathBuf>> {
    register_font()?;
    let labels: Vec<String> = series.iter().map(|(n, _)| n.clone()).collect();
    let chart = LineChart {
        caption: caption.into(),
        x_desc: x_desc.into(),
        y_desc: y_desc.into(),
        y_floor: AxisFloor::of_desc(y_desc),
        log_x,
        series: series
            .into_iter()
            .map(|(name, pts)| Series::new(name, pts))
            .collect(),
        threshold: None,
        breaks: Vec::new(),
        colors: Colors::of_labels(labels),
    };
    write_both(&chart, dir, stem)
}

/// Removes the PNG and SVG files a previous run left in `dir`, so a chart this run does not
/// draw (too few points now) cannot be mistaken for one of its results.
fn remove_old_charts(dir: &Path) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| anyhow!("reading {}: {e}", dir.display()))?;
    for entry in entries {
        let path = entry
            .map_err(|e| anyhow!("reading {}: {e}", dir.display()))?
            .path();
        if path.is_file() && path.extension().is_some_and(|e| e == "png" || e == "svg") {
            std::fs::remove_file(&path).map_err(|e| anyhow!("removing {}: {e}", path.display()))?;
        }
    }
    Ok(())
}

/// Writes every chart the data supports into `dir` (created if missing) and returns the
/// paths written, PNG and SVG for each chart. Empty results write nothing.
pub fn write_charts(results: &Results, dir: &Path) -> Result<Vec<PathBuf>> {
    Ok(write_charts_by_model(results, dir)?
        .into_iter()
        .map(|(_, path)| path)
        .collect())
}

/// [`write_charts`], with each path tagged by its model (`None` for cross-model charts).
pub fn write_charts_by_model(
    results: &Results,
    dir: &Path,
) -> Result<Vec<(Option<String>, PathBuf)>> {
    register_font()?;
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("creating {}: {e}", dir.display()))?;
    remove_old_charts(dir)?;
    let device = if results.device.is_empty() {
        "unknown device"
    } else {
        results.device.as_str()
    };
    let colors = Colors::new(results);
    let mut written = Vec::new();
    for model in models(results) {
        let tag = |paths: Vec<PathBuf>| paths.into_iter().map(|p| (Some(model.clone()), p));
        for (i, head) in model_slices(results, &model).into_iter().enumerate() {
            let Some(first) = head.first() else {
                continue;
            };
            // The headline slice keeps the model's name; the others name their slice.
            let stem = if i == 0 {
                slug(&model)
            } else {
                format!(
                    "{}_{}pts_{}",
                    slug(&model),
                    first.points,
                    first.resolution()
                )
            };
            let res = format!("{} ({} points)", first.resolution(), first.points);
            let accuracy: [(&str, &str, MetricFn, AxisFloor); 2] = [
                ("psnr", "PSNR (dB)", |r| r.scores.psnr, AxisFloor::PSNR),
                ("ssim", "SSIM", |r| r.scores.ssim, AxisFloor::SSIM),
            ];
            for (key, desc, metric, floor) in accuracy {
                let points = speed_accuracy(&head, metric);
                let chart = ParetoChart {
                    caption: format!("{model} {res}: {desc} vs GPU time, {device}"),
                    y_desc: desc.to_string(),
                    floor,
                    intervals: speed_intervals(&head, &points),
                    points,
                    references: reference_times(&head),
                    colors: colors.clone(),
                };
                written.extend(tag(write_both(
                    &chart,
                    dir,
                    &format!("{stem}_speed_{key}"),
                )?));
            }
            let chart = StackedPassChart::new(
                format!("{model} {res}: GPU time per pass, {device}"),
                &head,
                &colors,
            );
            written.extend(tag(write_both(&chart, dir, &format!("{stem}_passes"))?));
        }

        let of_model: Vec<&Record> = baseline(results).filter(|r| r.model == model).collect();
        let mut poses_seen: Vec<String> = Vec::new();
        for slice in path_slices(&of_model) {
            let first = slice[0];
            // Each pose's largest slice is named after the pose alone.
            let stem = if poses_seen.contains(&first.pose) {
                format!(
                    "{}_path_{}_{}pts_{}_{}lights",
                    slug(&model),
                    slug(&first.pose),
                    first.points,
                    first.resolution(),
                    first.lights
                )
            } else {
                poses_seen.push(first.pose.clone());
                format!("{}_path_{}", slug(&model), slug(&first.pose))
            };
            let series = slice
                .iter()
                .map(|r| {
                    let pts = r
                        .path_times
                        .iter()
                        .copied()
                        .zip(r.frame_samples_ms.iter().copied());
                    Series::new(r.label(), pts.collect())
                })
                .collect();
            let chart = LineChart::time(
                format!(
                    "{model} {} ({} points, {} light(s)): GPU time along path {:?}, {device}",
                    first.resolution(),
                    first.points,
                    first.lights,
                    first.pose
                ),
                "path time",
                false,
                series,
                &colors,
            );
            written.extend(tag(write_both(&chart, dir, &stem)?));
        }
        if let Some(points) = slice_with_most(&of_model, |r| r.points, |r| r.pixels()) {
            let slice: Vec<&Record> = of_model
                .iter()
                .copied()
                .filter(|r| r.points == points)
                .collect();
            let chart = LineChart::time(
                format!(
                    "{model} ({} points): GPU time vs resolution, {device}",
                    compact(points as f64)
                ),
                "pixels",
                false,
                time_series(&slice, Record::pixels),
                &colors,
            );
            written.extend(tag(write_both(
                &chart,
                dir,
                &format!("{}_time_vs_resolution", slug(&model)),
            )?));
        }
        if let Some(key) = slice_with_most(&of_model, |r| (r.points, r.pixels()), |r| r.lights) {
            let slice: Vec<&Record> = of_model
                .into_iter()
                .filter(|r| (r.points, r.pixels()) == key)
                .collect();
            let res = slice.first().map(|r| r.resolution()).unwrap_or_default();
            let chart = LineChart::time(
                format!("{model} {res}: GPU time vs lights, {device}"),
                "lights",
                false,
                time_series(&slice, |r| u64::from(r.lights)),
                &colors,
            );
            written.extend(tag(write_both(
                &chart,
                dir,
                &format!("{}_time_vs_lights", slug(&model)),
            )?));
        }
    }

    let mut resolutions: Vec<(u32, u32)> = baseline(results).map(|r| (r.width, r.height)).collect();
    resolutions.sort_unstable_by_key(|&(w, h)| (u64::from(w) * u64::from(h), w));
    resolutions.dedup();
    for res in resolutions {
        let slice: Vec<&Record> = baseline(results)
            .filter(|r| (r.width, r.height) == res)
            .collect();
        let chart = LineChart::time(
            format!("GPU time vs points at {}x{}, {device}", res.0, res.1),
            "points (log scale)",
            true,
            time_series(&slice, |r| r.points),
            &colors,
        );
        written.extend(
            write_both(&chart, dir, &format!("time_vs_points_{}x{}", res.0, res.1))?
                .into_iter()
                .map(|p| (None, p)),
        );
    }

    written.extend(write_stress_charts(results, dir, device, &colors)?);
    Ok(written)
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::eval::metrics::Scores;
    use crate::eval::results::PassTiming;

    pub(super) fn record(method: &str, size: &str, ms: f64, psnr: f64) -> Record {
        let params = if size.is_empty() {
            BTreeMap::new()
        } else {
            BTreeMap::from([("size".to_string(), size.to_string())])
        };
        Record {
            model: "bunny".into(),
            points: 1000,
            method: method.into(),
            params,
            width: 64,
            height: 64,
            pose: "default".into(),
            distance: Some(1.0),
            lights: 1,
            stress: None,
            stress_value: None,
            device: "GPU".into(),
            driver: "1.0".into(),
            passes: Vec::new(),
            frame_ms_median: ms,
            frame_ms_iqr: 0.1,
            frame_samples_ms: Vec::new(),
            path_times: Vec::new(),
            invocations: Vec::new(),
            points_per_second: 1000.0 / (ms / 1000.0),
            projected_points: None,
            projected_per_level: Vec::new(),
            scores: Scores {
                psnr: Some(psnr),
                ..Scores::default()
            },
        }
    }

    #[test]
    fn a_light_sweep_draws_time_vs_lights() {
        let mut results = Results::default();
        for (lights, ms) in [(0, 1.0), (1, 1.5), (16, 4.0)] {
            let mut r = record("perspective-phong", "", ms, 30.0);
            r.lights = lights;
            results.records.push(r);
        }
        let dir = std::env::temp_dir().join(format!("surfel_charts_lights_{}", std::process::id()));
        let written = write_charts(&results, &dir).unwrap();
        assert!(
            written.contains(&dir.join("bunny_time_vs_lights.png")),
            "{written:?}"
        );
        // One light count: no chart.
        results.records.retain(|r| r.lights == 1);
        let written = write_charts(&results, &dir).unwrap();
        assert!(!written
            .iter()
            .any(|p| p.to_string_lossy().contains("vs_lights")));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn charts_of_an_earlier_run_are_removed() {
        let dir = std::env::temp_dir().join(format!("surfel_charts_stale_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("old_time_vs_points.png"), b"stale").unwrap();
        std::fs::write(dir.join("notes.txt"), b"kept").unwrap();
        let written = write_charts(&Results::default(), &dir).unwrap();
        assert!(written.is_empty());
        assert!(!dir.join("old_time_vs_points.png").exists());
        assert!(dir.join("notes.txt").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn empty_results_write_nothing() {
        let dir = std::env::temp_dir().join(format!("surfel_charts_empty_{}", std::process::id()));
        let written = write_charts(&Results::default(), &dir).unwrap();
        assert!(written.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The passes of the kernel report: four families, numbered levels included.
    pub(super) fn kernel_passes() -> Vec<String> {
        let mut names: Vec<String> = [
            "mesh.raster",
            "mesh.resolve",
            "ewa.clear",
            "ewa.clear-accum",
            "ewa.clear-large",
            "ewa.visibility",
            "ewa.visibility-large",
            "ewa.accumulate",
            "ewa.accumulate-large",
            "ewa.resolve",
            "pyramid.clear",
            "pyramid.project",
            "pyramid.level0",
            "pyramid.copy",
            "pyramid.shade",
            "kernel.clear",
            "kernel.project",
            "kernel.level0",
            "kernel.resolve",
            "kernel.shade",
        ]
        .map(String::from)
        .to_vec();
        names.extend((1..=10).map(|i| format!("pyramid.analysis.{i}")));
        names.extend((0..=9).map(|i| format!("pyramid.synthesis.{i}")));
        names.extend((1..=9).map(|i| format!("kernel.analysis.{i}")));
        names.extend((0..=9).map(|i| format!("kernel.interpolate.{i}")));
        names
    }

    /// One record per family of `names`, named after it, with the family's passes.
    pub(super) fn records_with_passes(names: &[String]) -> Vec<Record> {
        let mut out: Vec<Record> = Vec::new();
        for name in names {
            let family = pass_family(name);
            let i = match out.iter().position(|r| r.method == family) {
                Some(i) => i,
                None => {
                    out.push(record(family, "", 10.0, 20.0));
                    out.len() - 1
                }
            };
            out[i].passes.push(PassTiming {
                name: name.clone(),
                median_ms: 1.0,
                iqr_ms: 0.0,
                samples_ms: Vec::new(),
            });
        }
        out
    }

    /// Draws `chart` into a bitmap of `size` pixels.
    #[test]
    fn charts_draw_each_time_interval_as_a_bar() {
        let spread = |ms: f64| (0..9).map(|i| ms * (0.9 + 0.025 * f64::from(i))).collect();
        let mut records = [
            record("points", "1", 1.0, 25.0),
            record("ewa", "", 3.0, 32.0),
            // Written before raw samples were kept: no interval.
            record("splat", "", 2.0, 30.0),
        ];
        for r in &mut records[..2] {
            r.frame_samples_ms = spread(r.frame_ms_median);
        }
        let refs: Vec<&Record> = records.iter().collect();
        let points = speed_accuracy(&refs, |r| r.scores.psnr);
        let intervals = speed_intervals(&refs, &points);
        let ci = records[1].frame_ci().expect("samples");
        assert_eq!(intervals[1], Some((ci.low, ci.high)));
        assert!(ci.low < 3.0 && ci.high > 3.0, "{ci:?}");
        assert_eq!(intervals[2], None);
        let series = time_series(&refs, |r| r.points);
        assert_eq!(series[0].intervals, [intervals[0]]);
        // Each bar is a line and two caps more than the chart without intervals.
        let svg = |intervals: Vec<Option<(f64, f64)>>| {
            let chart = ParetoChart {
                caption: "bars".into(),
                y_desc: "PSNR (dB)".into(),
                floor: AxisFloor::PSNR,
                points: points.clone(),
                intervals,
                references: Vec::new(),
                colors: Colors::new(&Results::default()),
            };
            let mut text = String::new();
            {
                let root = SVGBackend::with_string(&mut text, chart.size()).into_drawing_area();
                chart.draw(&root).unwrap();
                root.present().unwrap();
            }
            text.matches("<polyline").count()
        };
        assert_eq!(svg(intervals) - svg(vec![None; 3]), 6);
    }

    pub(super) fn draw_at(chart: &impl Chart, size: (u32, u32)) -> DrawResult {
        register_font().unwrap();
        let mut buffer = vec![0u8; size.0 as usize * size.1 as usize * 3];
        let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
        chart.draw(&root)?;
        root.present()?;
        Ok(())
    }
}

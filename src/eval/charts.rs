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
//!   [`LOG_TIME_RATIO`];
//! - time vs points, per resolution with at least two point counts
//!   (`time_vs_points_WxH`): the baseline records at that resolution, averaged per
//!   (label, points) across models;
//! - time vs resolution, per model: the baseline records at the point count with the most
//!   distinct resolutions, averaged per (label, pixels);
//! - time vs lights, per model: the baseline records at the (points, resolution) with the most
//!   distinct light counts, averaged per (label, lights) (002 ch. 6's light sweeps);
//! - metric vs stress, per model and stress kind: hole ratio (with the
//!   [`BREAK_HOLE_RATIO`] threshold and each method's first breaking value marked) and PSNR.
//!
//! A chart with fewer than two data points (line charts: two distinct x values) is skipped.
//! A method configuration has the same color in every chart of one results set, and so does
//! a pass ([`Colors`]).

use std::collections::BTreeMap;
use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::metrics::BREAK_HOLE_RATIO;
use super::results::{pareto_front, stability, MetricFn, Record, Results};

/// Pixel size of every chart.
pub const CHART_SIZE: (u32, u32) = (1024, 720);

/// A speed-vs-accuracy chart puts time on a log axis when the slowest plotted time is more
/// than this many times the fastest.
pub const LOG_TIME_RATIO: f64 = 10.0;

/// DejaVu Sans (Bitstream Vera license, see `assets/fonts/LICENSE`), used for PNG text.
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

type DrawResult = Result<(), Box<dyn Error + Send + Sync>>;

/// Registers the embedded font as `sans-serif` for plotters' text rendering (once).
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    ok.then_some(())
        .ok_or_else(|| anyhow!("the embedded DejaVu Sans font is invalid"))
}

/// A chart that can draw itself on any plotters backend.
trait Chart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static;

    /// Data points drawn; charts with fewer than two are skipped.
    fn points(&self) -> usize;
}

/// One color per method configuration ([`Record::label`]) and per pass name, the same in every
/// chart of a results set: indices into plotters' 99-color palette in sorted name order.
#[derive(Clone, Debug, Default)]
pub struct Colors {
    labels: Vec<String>,
    passes: Vec<String>,
}

impl Colors {
    pub fn new(results: &Results) -> Self {
        let mut labels: Vec<String> = results.records.iter().map(Record::label).collect();
        labels.sort();
        labels.dedup();
        let mut passes: Vec<String> = results
            .records
            .iter()
            .flat_map(|r| r.passes.iter().map(|p| p.name.clone()))
            .collect();
        passes.sort();
        passes.dedup();
        Self { labels, passes }
    }

    fn pick(names: &[String], name: &str) -> RGBAColor {
        let i = names.binary_search_by(|n| n.as_str().cmp(name));
        Palette99::pick(i.unwrap_or_else(|i| i)).to_rgba()
    }

    /// The color of method configuration `label`.
    pub fn label(&self, label: &str) -> RGBAColor {
        Self::pick(&self.labels, label)
    }

    /// The color of pass `name`.
    pub fn pass(&self, name: &str) -> RGBAColor {
        Self::pick(&self.passes, name)
    }
}

/// Draws the series legend in the style every chart shares.
fn draw_legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> DrawResult
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(position)
        .draw()?;
    Ok(())
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
    {
        let root = BitMapBackend::new(&png, CHART_SIZE).into_drawing_area();
        chart.draw(&root).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.into()))?;
    }
    {
        let root = SVGBackend::new(&svg, CHART_SIZE).into_drawing_area();
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

/// `[lo, hi]` of the values padded by 5 % (a single value by 5 % of its magnitude, at least 1,
/// so the axis keeps readable ticks).
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        (hi - lo) * 0.05
    } else {
        (lo.abs() * 0.05).max(1.0)
    };
    (lo - pad, hi + pad)
}

/// Compact number: 1.2k, 3.4M, 0.5.
fn compact(v: f64) -> String {
    let a = v.abs();
    let (scaled, suffix) = if a >= 1e9 {
        (v / 1e9, "G")
    } else if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    let text = format!("{scaled:.2}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    format!("{text}{suffix}")
}

/// Label of a position `v` on a log10 axis: the value it stands for, to two significant
/// digits (10k, 16k, 100k).
fn log_label(v: f64) -> String {
    let step = 10f64.powf(v.floor() - 1.0);
    compact((10f64.powf(v) / step).round() * step)
}

/// Labels to ask for on an x axis spanning `x0..x1`: about one per decade on a log axis.
fn log_label_count(log: bool, x0: f64, x1: f64) -> usize {
    if log {
        (x1 - x0).ceil() as usize + 1
    } else {
        10
    }
}

fn mean(values: &[f64]) -> Option<f64> {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    (!finite.is_empty()).then(|| finite.iter().sum::<f64>() / finite.len() as f64)
}

/// The axes of a speed-vs-accuracy chart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedAxes {
    /// Time range in plot coordinates: `log10(ms)` when `log_time`, else ms.
    pub x: (f64, f64),
    /// Accuracy range.
    pub y: (f64, f64),
    /// Time is plotted as `log10(ms)`.
    pub log_time: bool,
}

impl SpeedAxes {
    /// Axes fitting `points` (`(label, ms, accuracy)`, as from [`speed_accuracy`], which
    /// leaves out the reference): padded ranges of the finite values, with time on a log axis
    /// when every time is positive and the slowest is more than [`LOG_TIME_RATIO`] times the
    /// fastest.
    pub fn fit(points: &[(String, f64, f64)]) -> Self {
        let times = || points.iter().map(|p| p.1).filter(|t| t.is_finite());
        let fastest = times().fold(f64::INFINITY, f64::min);
        let slowest = times().fold(f64::NEG_INFINITY, f64::max);
        let log_time = fastest > 0.0 && slowest > LOG_TIME_RATIO * fastest;
        let mut axes = SpeedAxes {
            x: (0.0, 1.0),
            y: padded_range(points.iter().map(|p| p.2)),
            log_time,
        };
        axes.x = padded_range(times().map(|t| axes.x_of(t)));
        axes
    }

    /// Plot x of a time in ms.
    pub fn x_of(&self, ms: f64) -> f64 {
        if self.log_time {
            ms.log10()
        } else {
            ms
        }
    }

    /// The time axis' description, saying when it is logarithmic.
    pub fn x_desc(&self) -> &'static str {
        if self.log_time {
            "GPU time per frame (ms, log scale)"
        } else {
            "GPU time per frame (ms)"
        }
    }
}

/// Labelled scatter of (time, accuracy) with its Pareto front as a step line.
struct ParetoChart {
    caption: String,
    y_desc: String,
    /// `(label, ms, accuracy)`, without the reference.
    points: Vec<(String, f64, f64)>,
    /// `(label, ms)` of the reference configurations, named in the legend, not plotted.
    references: Vec<(String, f64)>,
    colors: Colors,
}

impl Chart for ParetoChart {
    fn points(&self) -> usize {
        self.points.len()
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let axes = SpeedAxes::fit(&self.points);
        let ((x0, x1), (y0, y1)) = (axes.x, axes.y);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.caption, ("sans-serif", 22))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        let x_fmt = |v: &f64| {
            if axes.log_time {
                log_label(*v)
            } else {
                compact(*v)
            }
        };
        chart
            .configure_mesh()
            .x_labels(log_label_count(axes.log_time, x0, x1))
            .x_label_formatter(&x_fmt)
            .x_desc(axes.x_desc())
            .y_desc(self.y_desc.as_str())
            .draw()?;
        let xy: Vec<(f64, f64)> = self.points.iter().map(|p| (axes.x_of(p.1), p.2)).collect();
        let front = pareto_front(&xy);
        let mut step = Vec::new();
        for (k, &i) in front.iter().enumerate() {
            if k > 0 {
                step.push((xy[i].0, xy[front[k - 1]].1));
            }
            step.push(xy[i]);
        }
        if let Some(&last) = front.last() {
            step.push((x1, xy[last].1));
        }
        chart
            .draw_series(LineSeries::new(step, RED.stroke_width(2)))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
        chart.draw_series(
            front
                .iter()
                .map(|&i| Circle::new(xy[i], 9, RED.stroke_width(2))),
        )?;
        for ((label, ..), &at) in self.points.iter().zip(&xy) {
            let color = self.colors.label(label);
            // Labels of points in the right third end at the point, so none runs off the plot.
            let right = at.0 > x0 + (x1 - x0) * 2.0 / 3.0;
            let (offset, anchor) = if right {
                ((-8, -14), HPos::Right)
            } else {
                ((8, -14), HPos::Left)
            };
            let style =
                TextStyle::from(("sans-serif", 14).into_font()).pos(Pos::new(anchor, VPos::Top));
            chart.draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 5, color.filled())
                    + Text::new(label.clone(), offset, style),
            ))?;
        }
        for (label, ms) in &self.references {
            chart
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                .label(format!("reference (not plotted): {label}, {ms:.1} ms"))
                .legend(|(x, y)| Cross::new((x + 10, y), 5, BLACK.stroke_width(2)));
        }
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight)
    }
}

/// Horizontal stacked bars: one bar per method configuration, one segment per pass.
struct StackedPassChart {
    caption: String,
    labels: Vec<String>,
    passes: Vec<String>,
    /// `ms[label][pass]`.
    ms: Vec<Vec<f64>>,
    colors: Colors,
}

impl Chart for StackedPassChart {
    fn points(&self) -> usize {
        self.labels.len()
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let total = self
            .ms
            .iter()
            .map(|row| row.iter().sum::<f64>())
            .fold(0.0, f64::max);
        // A segmented 0..m range has m + 1 bands, one per label.
        let n = self.labels.len() as i32;
        let longest = self.labels.iter().map(|l| l.len()).max().unwrap_or(0) as u32;
        let mut chart = ChartBuilder::on(root)
            .caption(&self.caption, ("sans-serif", 22))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size((longest * 8 + 20).clamp(60, 400))
            .build_cartesian_2d(
                0.0..total.max(f64::MIN_POSITIVE) * 1.25,
                (0..n - 1).into_segmented(),
            )?;
        let labels = &self.labels;
        let label_of = |v: &SegmentValue<i32>| match v {
            SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => usize::try_from(*i)
                .ok()
                .and_then(|i| labels.get(i))
                .cloned()
                .unwrap_or_default(),
            SegmentValue::Last => String::new(),
        };
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(self.labels.len())
            .y_label_formatter(&label_of)
            .x_desc("GPU time per frame (ms)")
            .draw()?;
        for (p, pass) in self.passes.iter().enumerate() {
            let color = self.colors.pass(pass);
            let bars = self.ms.iter().enumerate().map(|(row, times)| {
                let start: f64 = times[..p].iter().sum();
                let y = row as i32;
                let mut bar = Rectangle::new(
                    [
                        (start, SegmentValue::Exact(y)),
                        (start + times[p], SegmentValue::Exact(y + 1)),
                    ],
                    color.filled(),
                );
                bar.set_margin(6, 6, 0, 0);
                bar
            });
            chart
                .draw_series(bars)?
                .label(pass.as_str())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 12, y + 6)], color.filled())
                });
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight)
    }
}

/// One line per series; optional horizontal threshold and marked points.
struct LineChart {
    caption: String,
    x_desc: String,
    y_desc: String,
    /// Plot x as log10 (labels show the actual value).
    log_x: bool,
    series: Vec<(String, Vec<(f64, f64)>)>,
    /// `(y, legend)` drawn as a dashed horizontal line.
    threshold: Option<(f64, String)>,
    /// Points to highlight, `(x, y, note)`.
    marks: Vec<(f64, f64, String)>,
    colors: Colors,
}

impl LineChart {
    /// GPU time per frame against `x_desc`, one line per method configuration.
    fn time(
        caption: String,
        x_desc: &str,
        log_x: bool,
        series: Vec<(String, Vec<(f64, f64)>)>,
        colors: &Colors,
    ) -> Self {
        Self {
            caption,
            x_desc: x_desc.into(),
            y_desc: "GPU time per frame (ms)".into(),
            log_x,
            series,
            threshold: None,
            marks: Vec::new(),
            colors: colors.clone(),
        }
    }
}

impl Chart for LineChart {
    /// Distinct x values: lines over a single x show nothing.
    fn points(&self) -> usize {
        let mut xs: Vec<u64> = self
            .series
            .iter()
            .flat_map(|(_, pts)| pts.iter().map(|p| p.0.to_bits()))
            .collect();
        xs.sort_unstable();
        xs.dedup();
        xs.len()
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let tx = |x: f64| {
            if self.log_x {
                x.max(f64::MIN_POSITIVE).log10()
            } else {
                x
            }
        };
        let all = || self.series.iter().flat_map(|(_, pts)| pts.iter());
        let (x0, x1) = padded_range(all().map(|p| tx(p.0)));
        let ys = all()
            .map(|p| p.1)
            .chain(self.threshold.as_ref().map(|t| t.0));
        let (y0, y1) = padded_range(ys);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.caption, ("sans-serif", 22))
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        let log_x = self.log_x;
        let x_fmt = move |v: &f64| if log_x { log_label(*v) } else { compact(*v) };
        chart
            .configure_mesh()
            .x_labels(log_label_count(log_x, x0, x1))
            .x_desc(self.x_desc.as_str())
            .y_desc(self.y_desc.as_str())
            .x_label_formatter(&x_fmt)
            .draw()?;
        for (name, pts) in &self.series {
            let color = self.colors.label(name);
            let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (tx(x), y)).collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 4, color.filled())))?;
        }
        if let Some((y, legend)) = &self.threshold {
            let dashes = DashedLineSeries::new(vec![(x0, *y), (x1, *y)], 10, 6, BLACK.into());
            chart
                .draw_series(dashes)?
                .label(legend.as_str())
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        }
        for (x, y, note) in &self.marks {
            chart.draw_series(std::iter::once(
                EmptyElement::at((tx(*x), *y))
                    + Cross::new((0, 0), 9, RED.stroke_width(3))
                    + Text::new(note.clone(), (10, 6), ("sans-serif", 14)),
            ))?;
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)
    }
}

/// Writes a line chart of `series` (name, points) as `dir/stem.png` and `.svg` (for studies
/// outside the benchmark's results sets, e.g. the HPR report); nothing for fewer than two
/// distinct x values.
pub fn write_line_chart(
    dir: &Path,
    stem: &str,
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    log_x: bool,
    series: Vec<(String, Vec<(f64, f64)>)>,
) -> Result<Vec<PathBuf>> {
    register_font()?;
    let mut labels: Vec<String> = series.iter().map(|(n, _)| n.clone()).collect();
    labels.sort();
    labels.dedup();
    let chart = LineChart {
        caption: caption.into(),
        x_desc: x_desc.into(),
        y_desc: y_desc.into(),
        log_x,
        series,
        threshold: None,
        marks: Vec::new(),
        colors: Colors {
            labels,
            passes: Vec::new(),
        },
    };
    write_both(&chart, dir, stem)
}

/// Baseline (unstressed) records.
fn baseline(results: &Results) -> impl Iterator<Item = &Record> {
    results.records.iter().filter(|r| r.stress.is_none())
}

/// Distinct model names in first-appearance order.
pub fn models(results: &Results) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in &results.records {
        if !out.contains(&r.model) {
            out.push(r.model.clone());
        }
    }
    out
}

/// The baseline records of `model` grouped by (resolution, point count), each a slice the
/// speed-vs-accuracy and per-pass charts (and the report's Pareto sets) compare: the headline
/// slice (largest resolution and, within it, largest point count) first, then the others by
/// decreasing pixels and points.
pub fn model_slices<'a>(results: &'a Results, model: &str) -> Vec<Vec<&'a Record>> {
    // Keyed by (pixels, points, resolution), so the largest slice comes last.
    type Key = (u64, u64, (u32, u32));
    let mut slices: BTreeMap<Key, Vec<&Record>> = BTreeMap::new();
    for r in baseline(results).filter(|r| r.model == model) {
        slices
            .entry((r.pixels(), r.points, (r.width, r.height)))
            .or_default()
            .push(r);
    }
    slices.into_values().rev().collect()
}

/// Per label (in first-appearance order): the records with that label.
fn by_label<'a>(records: &[&'a Record]) -> Vec<(String, Vec<&'a Record>)> {
    let mut out: Vec<(String, Vec<&Record>)> = Vec::new();
    for r in records {
        let label = r.label();
        match out.iter_mut().find(|(l, _)| *l == label) {
            Some((_, group)) => group.push(r),
            None => out.push((label, vec![r])),
        }
    }
    out
}

/// `(label, mean frame ms, mean metric)` per label, skipping labels without a finite metric
/// and the reference ([`Record::is_reference`]), whose accuracy is its own.
pub fn speed_accuracy(
    records: &[&Record],
    metric: impl Fn(&Record) -> Option<f64>,
) -> Vec<(String, f64, f64)> {
    let measured: Vec<&Record> = records
        .iter()
        .copied()
        .filter(|r| !r.is_reference())
        .collect();
    by_label(&measured)
        .into_iter()
        .filter_map(|(label, group)| {
            let ms: Vec<f64> = group.iter().map(|r| r.frame_ms_median).collect();
            let acc: Vec<f64> = group.iter().filter_map(|r| metric(r)).collect();
            Some((label, mean(&ms)?, mean(&acc)?))
        })
        .collect()
}

/// `(label, mean frame ms)` per configuration of the reference among `records`.
pub fn reference_times(records: &[&Record]) -> Vec<(String, f64)> {
    let references: Vec<&Record> = records
        .iter()
        .copied()
        .filter(|r| r.is_reference())
        .collect();
    by_label(&references)
        .into_iter()
        .filter_map(|(label, group)| {
            let ms: Vec<f64> = group.iter().map(|r| r.frame_ms_median).collect();
            Some((label, mean(&ms)?))
        })
        .collect()
}

/// Per label: points sorted by x of the mean frame time over records sharing `x(record)`.
fn time_series(records: &[&Record], x: impl Fn(&Record) -> u64) -> Vec<(String, Vec<(f64, f64)>)> {
    by_label(records)
        .into_iter()
        .map(|(label, group)| {
            let mut at: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
            for r in group {
                at.entry(x(r)).or_default().push(r.frame_ms_median);
            }
            let pts = at
                .into_iter()
                .filter_map(|(x, ms)| Some((x as f64, mean(&ms)?)))
                .collect();
            (label, pts)
        })
        .collect()
}

/// The value of `key` among `records` with the most distinct values of `other`.
fn slice_with_most<K: Ord + Copy, O: Ord>(
    records: &[&Record],
    key: impl Fn(&Record) -> K,
    other: impl Fn(&Record) -> O,
) -> Option<K> {
    let mut distinct: BTreeMap<K, std::collections::BTreeSet<O>> = BTreeMap::new();
    for r in records {
        distinct.entry(key(r)).or_default().insert(other(r));
    }
    distinct
        .into_iter()
        .max_by_key(|(_, set)| set.len())
        .map(|(k, _)| k)
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
            let accuracy: [(&str, &str, MetricFn); 2] = [
                ("psnr", "PSNR (dB)", |r| r.scores.psnr),
                ("ssim", "SSIM", |r| r.scores.ssim),
            ];
            for (key, desc, metric) in accuracy {
                let chart = ParetoChart {
                    caption: format!("{model} {res}: {desc} vs GPU time, {device}"),
                    y_desc: desc.to_string(),
                    points: speed_accuracy(&head, metric),
                    references: reference_times(&head),
                    colors: colors.clone(),
                };
                written.extend(tag(write_both(
                    &chart,
                    dir,
                    &format!("{stem}_speed_{key}"),
                )?));
            }
            let groups = by_label(&head);
            let mut passes: Vec<String> = Vec::new();
            for p in head.iter().flat_map(|r| &r.passes) {
                if !passes.contains(&p.name) {
                    passes.push(p.name.clone());
                }
            }
            let ms = groups
                .iter()
                .map(|(_, group)| {
                    passes
                        .iter()
                        .map(|name| {
                            let v: Vec<f64> = group
                                .iter()
                                .filter_map(|r| r.passes.iter().find(|p| &p.name == name))
                                .map(|p| p.median_ms)
                                .collect();
                            mean(&v).unwrap_or(0.0).max(0.0)
                        })
                        .collect()
                })
                .collect();
            let chart = StackedPassChart {
                caption: format!("{model} {res}: GPU time per pass, {device}"),
                labels: groups.into_iter().map(|(l, _)| l).collect(),
                passes,
                ms,
                colors: colors.clone(),
            };
            written.extend(tag(write_both(&chart, dir, &format!("{stem}_passes"))?));
        }

        let of_model: Vec<&Record> = baseline(results).filter(|r| r.model == model).collect();
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

fn write_stress_charts(
    results: &Results,
    dir: &Path,
    device: &str,
    colors: &Colors,
) -> Result<Vec<(Option<String>, PathBuf)>> {
    let mut written = Vec::new();
    let stab = stability(results);
    let mut keys: Vec<(String, String)> = Vec::new();
    for r in &results.records {
        if let Some(kind) = &r.stress {
            let key = (r.model.clone(), kind.clone());
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
    }
    for (model, kind) in keys {
        let unit = kind
            .parse::<super::config::StressKind>()
            .map(|k| k.unit().to_string())
            .unwrap_or_else(|_| kind.clone());
        let curves: Vec<_> = stab
            .iter()
            .filter(|s| s.model == model && s.kind == kind)
            .collect();
        let mut series = Vec::new();
        let mut marks = Vec::new();
        for s in &curves {
            let mut pts: Vec<(f64, f64)> = s.curve.iter().map(|&(v, h)| (v, h * 100.0)).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            if let Some(v) = s.breaks_at {
                if let Some(&(_, h)) = s.curve.iter().find(|(x, _)| *x == v) {
                    marks.push((v, h * 100.0, format!("{} breaks at {v}", s.label)));
                }
            }
            series.push((s.label.clone(), pts));
        }
        let stem = format!("{}_stress_{}", slug(&model), slug(&kind));
        let chart = LineChart {
            caption: format!("{model}: holes vs {kind} stress, {device}"),
            x_desc: unit.clone(),
            y_desc: "hole ratio (%)".into(),
            log_x: false,
            series,
            threshold: Some((
                BREAK_HOLE_RATIO * 100.0,
                format!("breaks above {}%", BREAK_HOLE_RATIO * 100.0),
            )),
            marks,
            colors: colors.clone(),
        };
        let tag = |paths: Vec<PathBuf>| paths.into_iter().map(|p| (Some(model.clone()), p));
        written.extend(tag(write_both(&chart, dir, &format!("{stem}_holes"))?));

        let stressed: Vec<&Record> = results
            .records
            .iter()
            .filter(|r| r.model == model && r.stress.as_deref() == Some(kind.as_str()))
            .collect();
        let series = by_label(&stressed)
            .into_iter()
            .map(|(label, group)| {
                let mut at: BTreeMap<u64, (f64, Vec<f64>)> = BTreeMap::new();
                for r in group {
                    if let (Some(v), Some(p)) = (r.stress_value, r.scores.psnr) {
                        at.entry(v.to_bits()).or_insert((v, Vec::new())).1.push(p);
                    }
                }
                let mut pts: Vec<(f64, f64)> = at
                    .into_values()
                    .filter_map(|(v, ps)| Some((v, mean(&ps)?)))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                (label, pts)
            })
            .collect();
        let chart = LineChart {
            caption: format!("{model}: PSNR vs {kind} stress, {device}"),
            x_desc: unit,
            y_desc: "PSNR (dB)".into(),
            log_x: false,
            series,
            threshold: None,
            marks: Vec::new(),
            colors: colors.clone(),
        };
        written.extend(tag(write_both(&chart, dir, &format!("{stem}_psnr"))?));
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::eval::metrics::{Scores, PSNR_CAP_DB};
    use crate::eval::results::REFERENCE_METHOD;

    fn record(method: &str, size: &str, ms: f64, psnr: f64) -> Record {
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
            frame_ms_spread: 0.1,
            points_per_second: 1000.0 / (ms / 1000.0),
            samples: None,
            samples_per_level: Vec::new(),
            scores: Scores {
                psnr: Some(psnr),
                ..Scores::default()
            },
        }
    }

    fn axes_of(records: &[Record]) -> (Vec<(String, f64, f64)>, SpeedAxes) {
        let refs: Vec<&Record> = records.iter().collect();
        let points = speed_accuracy(&refs, |r| r.scores.psnr);
        let axes = SpeedAxes::fit(&points);
        (points, axes)
    }

    #[test]
    fn speed_axes_leave_out_the_reference_and_infinite_scores() {
        let records = [
            record("points", "1", 2.0, 20.0),
            record("points", "2", 3.0, 25.0),
            record(REFERENCE_METHOD, "", 170.0, PSNR_CAP_DB),
            record("splat", "", 4.0, f64::INFINITY),
        ];
        let (points, axes) = axes_of(&records);
        let labels: Vec<&str> = points.iter().map(|p| p.0.as_str()).collect();
        assert_eq!(labels, ["points(size=1)", "points(size=2)"]);
        // The axes fit the two measured methods only: 2..3 ms and 20..25 dB, padded by 5 %.
        assert!(!axes.log_time);
        assert!((axes.x.0 - 1.95).abs() < 1e-9 && (axes.x.1 - 3.05).abs() < 1e-9);
        assert!((axes.y.0 - 19.75).abs() < 1e-9 && (axes.y.1 - 25.25).abs() < 1e-9);
        assert_eq!(axes.x_desc(), "GPU time per frame (ms)");
        let refs: Vec<&Record> = records.iter().collect();
        assert_eq!(
            reference_times(&refs),
            [(REFERENCE_METHOD.to_string(), 170.0)]
        );
    }

    #[test]
    fn speed_axes_switch_to_log_time_beyond_ten_times() {
        let (_, axes) = axes_of(&[
            record("points", "1", 1.0, 20.0),
            record("points", "8", 50.0, 30.0),
        ]);
        assert!(axes.log_time);
        let span = 50f64.log10();
        assert!((axes.x.0 + 0.05 * span).abs() < 1e-9);
        assert!((axes.x.1 - 1.05 * span).abs() < 1e-9);
        assert!((axes.x_of(100.0) - 2.0).abs() < 1e-12);
        assert!(axes.x_desc().contains("log scale"));
        let (_, axes) = axes_of(&[
            record("points", "1", 1.0, 20.0),
            record("points", "8", 9.0, 30.0),
        ]);
        assert!(!axes.log_time);
        let (_, axes) = axes_of(&[
            record("points", "1", 0.0, 20.0),
            record("points", "8", 50.0, 30.0),
        ]);
        assert!(!axes.log_time, "a zero time cannot go on a log axis");
    }

    #[test]
    fn log_labels_show_the_value() {
        assert_eq!(log_label(0.0), "1");
        assert_eq!(log_label(2.0), "100");
        assert_eq!(log_label(1.2), "16");
    }

    #[test]
    fn compact_numbers_and_slugs() {
        assert_eq!(compact(1500.0), "1.5k");
        assert_eq!(compact(2_000_000.0), "2M");
        assert_eq!(compact(0.25), "0.25");
        assert_eq!(compact(3.0), "3");
        assert_eq!(slug("my model/v2.ply"), "my_model_v2_ply");
    }

    #[test]
    fn padded_range_handles_degenerate_input() {
        assert_eq!(padded_range(std::iter::empty()), (0.0, 1.0));
        assert_eq!(padded_range([2.0].into_iter()), (1.0, 3.0));
        let (lo, hi) = padded_range([0.0, 10.0, f64::NAN].into_iter());
        assert_eq!((lo, hi), (-0.5, 10.5));
    }

    #[test]
    fn a_single_large_value_gets_a_readable_range() {
        // One resolution (256x256 = 65,536 pixels) used to give ticks 65.53k..65.54k.
        let (lo, hi) = padded_range([65_536.0].into_iter());
        assert!((lo - 62_259.2).abs() < 1e-6 && (hi - 68_812.8).abs() < 1e-6);
    }

    #[test]
    fn line_charts_need_two_distinct_x_values() {
        let chart = |xs: &[f64]| LineChart {
            caption: String::new(),
            x_desc: String::new(),
            y_desc: String::new(),
            log_x: false,
            series: vec![
                ("a".into(), xs.iter().map(|&x| (x, 1.0)).collect()),
                ("b".into(), xs.iter().map(|&x| (x, 2.0)).collect()),
            ],
            threshold: None,
            marks: Vec::new(),
            colors: Colors::default(),
        };
        assert_eq!(chart(&[65_536.0]).points(), 1);
        assert_eq!(chart(&[65_536.0, 262_144.0]).points(), 2);
    }

    #[test]
    fn a_method_keeps_its_color_across_charts_and_result_sets() {
        let mut results = Results::default();
        for (method, size) in [("points", "1"), ("points", "2"), ("compute", "")] {
            results.records.push(record(method, size, 1.0, 30.0));
        }
        let colors = Colors::new(&results);
        let labels: Vec<String> = results.records.iter().map(Record::label).collect();
        let picked: Vec<RGBAColor> = labels.iter().map(|l| colors.label(l)).collect();
        assert_ne!(picked[0], picked[1]);
        assert_ne!(picked[1], picked[2]);
        // Record order does not matter: the palette follows sorted labels.
        results.records.reverse();
        let again = Colors::new(&results);
        for (l, c) in labels.iter().zip(&picked) {
            assert_eq!(again.label(l), *c, "{l}");
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
}

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
//! - metric vs stress, per model and stress kind: hole ratio (with the
//!   [`BREAK_HOLE_RATIO`] threshold and each method's first breaking value marked, methods
//!   breaking at one point sharing a note) and PSNR.
//!
//! A chart with fewer than two data points (line charts: two distinct x values) is skipped.
//! A method configuration has the same color in every chart of one results set, and so does
//! a pass: a shade of its family's hue ([`Colors`]); a line chart over several models draws
//! each model's series with its own marker and dash. Legends sit outside the data, beside the
//! plot (below it on speed-vs-accuracy charts), and a chart whose legend needs more rows than
//! [`CHART_SIZE`] holds grows taller. An accuracy axis never spans less than its
//! [`AxisFloor`]; when all values lie closer than that, the line under the caption says so.

use std::collections::BTreeMap;
use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{anyhow, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::metrics::BREAK_HOLE_RATIO;
use super::results::{pareto_front, stability, MetricFn, Record, Results};

/// Pixel size of every chart, unless its legend needs a taller one.
pub const CHART_SIZE: (u32, u32) = (1024, 720);

/// A speed-vs-accuracy chart puts time on a log axis when the slowest plotted time is more
/// than this many times the fastest.
pub const LOG_TIME_RATIO: f64 = 10.0;

/// Height of one legend row in pixels.
const LEGEND_ROW: i32 = 18;
/// Space inside a legend's box around its rows.
const LEGEND_PAD: i32 = 8;
/// Room of a legend row's swatch, the gap after it included.
const SWATCH: i32 = 30;
/// Indent of the rows under a legend's headings.
const INDENT: i32 = 10;
/// A chart's height beyond its legend: caption, note line, margins.
const ABOVE_AND_BELOW_LEGEND: i32 = 130;

/// DejaVu Sans (Bitstream Vera license, see `assets/fonts/LICENSE`), used for PNG text.
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

type DrawResult = Result<(), Box<dyn Error + Send + Sync>>;

type Plot<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

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

    /// Pixel size: [`CHART_SIZE`], taller where the legend needs it.
    fn size(&self) -> (u32, u32) {
        CHART_SIZE
    }
}

/// The height a chart needs for a legend of `rows` beside or below its plot.
fn size_for_legend(rows: usize) -> (u32, u32) {
    let needed = legend_height(rows) + ABOVE_AND_BELOW_LEGEND;
    (CHART_SIZE.0, CHART_SIZE.1.max(needed.max(0) as u32))
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

/// Hues (degrees) of the first pass families in sorted order, 45° apart; further families
/// step around the circle by the golden angle.
const FAMILY_HUES: [f64; 8] = [210.0, 30.0, 120.0, 345.0, 255.0, 165.0, 300.0, 75.0];

/// One color per method configuration ([`Record::label`]) and per pass entry ([`pass_entry`]),
/// the same in every chart of a results set: labels take plotters' 99-color palette in
/// sorted order; each pass family ([`pass_family`]) a hue of its own, its entries shades of
/// it, from dark to light in sorted order.
#[derive(Clone, Debug, Default)]
pub struct Colors {
    labels: Vec<String>,
    /// Per pass family, sorted: its entries, sorted.
    families: Vec<(String, Vec<String>)>,
}

impl Colors {
    pub fn new(results: &Results) -> Self {
        let mut labels: Vec<String> = results.records.iter().map(Record::label).collect();
        labels.sort();
        labels.dedup();
        let mut families: BTreeMap<String, Vec<String>> = BTreeMap::new();
        for pass in results.records.iter().flat_map(|r| &r.passes) {
            let entry = pass_entry(&pass.name);
            let of = families.entry(pass_family(&entry).to_string()).or_default();
            if let Err(i) = of.binary_search(&entry) {
                of.insert(i, entry);
            }
        }
        Self {
            labels,
            families: families.into_iter().collect(),
        }
    }

    /// Colors for the series names `labels` alone (charts without passes).
    fn of_labels(mut labels: Vec<String>) -> Self {
        labels.sort();
        labels.dedup();
        Self {
            labels,
            families: Vec::new(),
        }
    }

    /// The color of method configuration `label`.
    pub fn label(&self, label: &str) -> RGBAColor {
        let i = self.labels.binary_search_by(|n| n.as_str().cmp(label));
        Palette99::pick(i.unwrap_or_else(|i| i)).to_rgba()
    }

    /// Hue (degrees), saturation and lightness of pass `name` (any pass of its entry): the
    /// hue of its family, varied by at most 12° between entries, and a lightness from 0.3 (the
    /// first entry) to 0.72 (the last).
    pub fn pass_hsl(&self, name: &str) -> (f64, f64, f64) {
        let entry = pass_entry(name);
        let family = pass_family(&entry);
        let f = self
            .families
            .binary_search_by(|(n, _)| n.as_str().cmp(family))
            .unwrap_or_else(|i| i);
        let hue = FAMILY_HUES
            .get(f)
            .copied()
            .unwrap_or_else(|| (FAMILY_HUES[0] + f as f64 * 137.508) % 360.0);
        let (k, n) = self.families.get(f).map_or((0, 1), |(_, entries)| {
            (
                entries.binary_search(&entry).unwrap_or_else(|i| i),
                entries.len(),
            )
        });
        let lightness = if n > 1 {
            0.3 + 0.42 * k.min(n - 1) as f64 / (n - 1) as f64
        } else {
            0.45
        };
        let jitter = (k % 3) as f64 * 6.0 - 6.0;
        ((hue + jitter).rem_euclid(360.0), 0.75, lightness)
    }

    /// The color of pass `name` ([`Colors::pass_hsl`]).
    pub fn pass(&self, name: &str) -> RGBAColor {
        let (h, s, l) = self.pass_hsl(name);
        HSLColor(h / 360.0, s, l).to_rgba()
    }
}

/// The shape of a line chart's data points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Marker {
    Circle,
    Triangle,
    Square,
}

/// How a line chart draws the series of one model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SeriesStyle {
    marker: Marker,
    /// The marker is an outline.
    hollow: bool,
    dashed: bool,
}

impl SeriesStyle {
    /// The style of a chart's `i`-th model: six distinct markers (filled, then outlined),
    /// alternately on solid and dashed lines, then again.
    fn nth(i: usize) -> Self {
        Self {
            marker: [Marker::Circle, Marker::Triangle, Marker::Square][i % 3],
            hollow: i % 6 >= 3,
            dashed: i % 2 == 1,
        }
    }

    fn marker_style(&self, color: RGBAColor) -> ShapeStyle {
        if self.hollow {
            color.stroke_width(2)
        } else {
            color.filled()
        }
    }

    /// Draws the markers at `pts` (plot coordinates).
    fn markers<DB: DrawingBackend>(
        &self,
        chart: &mut Plot<DB>,
        pts: &[(f64, f64)],
        color: RGBAColor,
    ) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let style = self.marker_style(color);
        match self.marker {
            Marker::Circle => {
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, style)))?;
            }
            Marker::Triangle => {
                chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 6, style)))?;
            }
            Marker::Square => {
                chart
                    .draw_series(pts.iter().map(|&p| {
                        EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], style)
                    }))?;
            }
        }
        Ok(())
    }

    /// Draws the line through `pts` (plot coordinates).
    fn line<DB: DrawingBackend>(
        &self,
        chart: &mut Plot<DB>,
        pts: &[(f64, f64)],
        color: RGBAColor,
    ) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let style = color.stroke_width(2);
        if self.dashed {
            chart.draw_series(DashedLineSeries::new(pts.to_vec(), 8, 5, style))?;
        } else {
            chart.draw_series(LineSeries::new(pts.to_vec(), style))?;
        }
        Ok(())
    }

    /// Draws a short line with the marker in its middle, from pixel `(x, y)` of `area`.
    fn swatch<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        (x, y): (i32, i32),
        color: RGBAColor,
    ) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        let style = color.stroke_width(2);
        let ends = vec![(x, y), (x + 22, y)];
        if self.dashed {
            area.draw(&DashedPathElement::new(ends, 5, 3, style))?;
        } else {
            area.draw(&PathElement::new(ends, style))?;
        }
        let at = (x + 11, y);
        let fill = self.marker_style(color);
        match self.marker {
            Marker::Circle => area.draw(&Circle::new(at, 4, fill))?,
            Marker::Triangle => area.draw(&TriangleMarker::new(at, 6, fill))?,
            Marker::Square => area.draw(&Rectangle::new(
                [(at.0 - 4, at.1 - 4), (at.0 + 4, at.1 + 4)],
                fill,
            ))?,
        }
        Ok(())
    }
}

/// What a legend row shows before its text.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Swatch {
    /// Nothing: a heading, flush left, over the indented rows that follow it.
    Heading,
    /// A filled block (a pass, a series' color).
    Block(RGBAColor),
    /// A line in a series' style.
    Line(RGBAColor, SeriesStyle),
    /// A dashed black line (a threshold).
    Threshold,
    /// A thick red line (the Pareto front).
    Front,
    /// A black cross (a configuration named but not plotted).
    Cross,
}

/// One row of a legend.
#[derive(Clone, Debug, PartialEq)]
struct LegendRow {
    text: String,
    swatch: Swatch,
}

impl LegendRow {
    fn new(text: impl Into<String>, swatch: Swatch) -> Self {
        Self {
            text: text.into(),
            swatch,
        }
    }
}

/// Height of the box of a legend of `rows` rows.
fn legend_height(rows: usize) -> i32 {
    rows as i32 * LEGEND_ROW + 2 * LEGEND_PAD
}

fn legend_font() -> TextStyle<'static> {
    TextStyle::from(("sans-serif", 14).into_font())
}

/// Offset of the swatch and of the text of `row` from the legend box's left edge.
fn legend_offsets(row: &LegendRow, headings: bool) -> (i32, i32) {
    let indent = if headings { INDENT } else { 0 };
    match row.swatch {
        Swatch::Heading => (LEGEND_PAD, LEGEND_PAD),
        _ => (LEGEND_PAD + indent, LEGEND_PAD + indent + SWATCH),
    }
}

/// The width a legend of `rows` needs on `area` (text measured there), at most `max`.
fn legend_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    rows: &[LegendRow],
    max: i32,
) -> Result<i32, Box<dyn Error + Send + Sync>>
where
    DB::ErrorType: 'static,
{
    let headings = rows.iter().any(|r| r.swatch == Swatch::Heading);
    let font = legend_font();
    let mut width = 0;
    for row in rows {
        let (w, _) = area.estimate_text_size(&row.text, &font)?;
        width = width.max(legend_offsets(row, headings).1 + w as i32 + LEGEND_PAD);
    }
    Ok(width.min(max))
}

/// `text`, shortened with "…" until it is at most `width` pixels wide on `area`.
fn fit_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    width: i32,
) -> Result<String, Box<dyn Error + Send + Sync>>
where
    DB::ErrorType: 'static,
{
    let font = legend_font();
    let mut chars: Vec<char> = text.chars().collect();
    let mut out = text.to_string();
    while !chars.is_empty() && area.estimate_text_size(&out, &font)?.0 as i32 > width {
        chars.pop();
        out = chars.iter().collect::<String>() + "…";
    }
    Ok(out)
}

/// Draws `rows` in a white box with a black border, `width` wide, its top-left corner at
/// pixel `at` of `area`; a text too long for the box is shortened with "…". Fails when the
/// box does not fit in `area`, so no chart is written with part of its legend cut off.
fn draw_legend_box<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    width: i32,
    rows: &[LegendRow],
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    if rows.is_empty() {
        return Ok(());
    }
    let height = legend_height(rows.len());
    let (w, h) = area.dim_in_pixel();
    if x < 0 || y < 0 || x + width > w as i32 || y + height > h as i32 {
        return Err(format!(
            "a legend of {} rows ({width}x{height} px at {x},{y}) does not fit in {w}x{h} px",
            rows.len()
        )
        .into());
    }
    area.draw(&Rectangle::new(
        [(x, y), (x + width, y + height)],
        WHITE.filled(),
    ))?;
    area.draw(&Rectangle::new([(x, y), (x + width, y + height)], BLACK))?;
    let headings = rows.iter().any(|r| r.swatch == Swatch::Heading);
    let font = legend_font().pos(Pos::new(HPos::Left, VPos::Center));
    for (i, row) in rows.iter().enumerate() {
        let mid = y + LEGEND_PAD + i as i32 * LEGEND_ROW + LEGEND_ROW / 2;
        let (swatch, text) = legend_offsets(row, headings);
        let sx = x + swatch;
        match row.swatch {
            Swatch::Heading => {}
            Swatch::Block(color) => {
                area.draw(&Rectangle::new(
                    [(sx + 5, mid - 6), (sx + 17, mid + 6)],
                    color.filled(),
                ))?;
            }
            Swatch::Line(color, style) => style.swatch(area, (sx, mid), color)?,
            Swatch::Threshold => {
                area.draw(&DashedPathElement::new(
                    vec![(sx, mid), (sx + 22, mid)],
                    5,
                    3,
                    BLACK,
                ))?;
            }
            Swatch::Front => {
                area.draw(&PathElement::new(
                    vec![(sx, mid), (sx + 22, mid)],
                    RED.stroke_width(2),
                ))?;
            }
            Swatch::Cross => {
                area.draw(&Cross::new((sx + 11, mid), 5, BLACK.stroke_width(2)))?;
            }
        }
        let shown = fit_text(area, &row.text, width - text - LEGEND_PAD)?;
        area.draw(&Text::new(shown, (x + text, mid), font.clone()))?;
    }
    Ok(())
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

/// The narrowest span an axis of a metric may have: differences below it are within the
/// metric's noise for the comparisons these charts make, and must not fill the chart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisFloor {
    /// The narrowest span of the axis, in the metric's unit.
    pub min_span: f64,
    /// Unit appended to a span in the note, with its leading space.
    unit: &'static str,
    /// Decimals of a span in the note.
    decimals: usize,
}

impl AxisFloor {
    /// No floor (times, counts).
    pub const NONE: Self = Self {
        min_span: 0.0,
        unit: "",
        decimals: 2,
    };
    /// PSNR axes span at least 1 dB.
    pub const PSNR: Self = Self {
        min_span: 1.0,
        unit: " dB",
        decimals: 2,
    };
    /// SSIM axes span at least 0.01.
    pub const SSIM: Self = Self {
        min_span: 0.01,
        unit: "",
        decimals: 4,
    };

    /// The floor of an axis described as `desc`: PSNR for "PSNR (dB)" and "PSNR lost … (dB)",
    /// SSIM for "SSIM", none otherwise.
    pub fn of_desc(desc: &str) -> Self {
        if desc.starts_with("PSNR") {
            Self::PSNR
        } else if desc.starts_with("SSIM") {
            Self::SSIM
        } else {
            Self::NONE
        }
    }

    /// The note under a chart's caption when the finite `values` span less than the floor:
    /// "all values within 0.06 dB (axis spans at least 1 dB)".
    pub fn note(&self, values: impl Iterator<Item = f64>) -> Option<String> {
        let (lo, hi) = finite_bounds(values)?;
        let span = hi - lo;
        (span < self.min_span).then(|| {
            format!(
                "all values within {span:.*}{unit} (axis spans at least {}{unit})",
                self.decimals,
                self.min_span,
                unit = self.unit
            )
        })
    }
}

/// The smallest and largest finite value, if any.
fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    (lo <= hi).then_some((lo, hi))
}

/// `[lo, hi]` of the values padded by 5 % (a single value by 5 % of its magnitude, at least 1,
/// so the axis keeps readable ticks), widened about its centre to at least `min_span`.
fn padded_range(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let Some((lo, hi)) = finite_bounds(values) else {
        return (0.0, 1.0);
    };
    let pad = if hi > lo {
        (hi - lo) * 0.05
    } else {
        (lo.abs() * 0.05).max(1.0)
    };
    let (lo, hi) = (lo - pad, hi + pad);
    if hi - lo < min_span {
        let centre = (lo + hi) / 2.0;
        (centre - min_span / 2.0, centre + min_span / 2.0)
    } else {
        (lo, hi)
    }
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
    /// leaves out the reference): padded ranges of the finite values, the accuracy range at
    /// least `floor` wide, with time on a log axis when every time is positive and the
    /// slowest is more than [`LOG_TIME_RATIO`] times the fastest.
    pub fn fit(points: &[(String, f64, f64)], floor: AxisFloor) -> Self {
        let times = || points.iter().map(|p| p.1).filter(|t| t.is_finite());
        let fastest = times().fold(f64::INFINITY, f64::min);
        let slowest = times().fold(f64::NEG_INFINITY, f64::max);
        let log_time = fastest > 0.0 && slowest > LOG_TIME_RATIO * fastest;
        let mut axes = SpeedAxes {
            x: (0.0, 1.0),
            y: padded_range(points.iter().map(|p| p.2), floor.min_span),
            log_time,
        };
        axes.x = padded_range(times().map(|t| axes.x_of(t)), 0.0);
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
    /// The accuracy axis' floor.
    floor: AxisFloor,
    /// `(label, ms, accuracy)`, without the reference.
    points: Vec<(String, f64, f64)>,
    /// `(label, ms)` of the reference configurations, named in the legend, not plotted.
    references: Vec<(String, f64)>,
    colors: Colors,
}

impl ParetoChart {
    fn legend(&self) -> Vec<LegendRow> {
        let mut rows = vec![LegendRow::new("Pareto front", Swatch::Front)];
        rows.extend(self.references.iter().map(|(label, ms)| {
            LegendRow::new(
                format!("reference (not plotted): {label}, {ms:.1} ms"),
                Swatch::Cross,
            )
        }));
        rows
    }
}

impl Chart for ParetoChart {
    fn points(&self) -> usize {
        self.points.len()
    }

    fn size(&self) -> (u32, u32) {
        size_for_legend(self.legend().len())
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let axes = SpeedAxes::fit(&self.points, self.floor);
        let note = self.floor.note(self.points.iter().map(|p| p.2));
        let area = titled(root, &self.caption, note.as_deref())?;
        let rows = self.legend();
        let (width, height) = area.dim_in_pixel();
        let (plot, below) = area.split_vertically(height as i32 - legend_height(rows.len()) - 12);
        let ((x0, x1), (y0, y1)) = (axes.x, axes.y);
        let mut chart = ChartBuilder::on(&plot)
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
        chart.draw_series(LineSeries::new(step, RED.stroke_width(2)))?;
        chart.draw_series(
            front
                .iter()
                .map(|&i| Circle::new(xy[i], 9, RED.stroke_width(2))),
        )?;
        for ((label, ..), &at) in self.points.iter().zip(&xy) {
            let color = self.colors.label(label);
            chart.draw_series(std::iter::once(Circle::new(at, 5, color.filled())))?;
        }
        let labels: Vec<((i32, i32), String)> = self
            .points
            .iter()
            .zip(&xy)
            .map(|((label, ..), at)| (chart.backend_coord(at), label.clone()))
            .collect();
        draw_labels(root, &labels, -16, chart.plotting_area().get_pixel_range())?;
        // Under the plot, aligned with its left edge (margin and y label area).
        let legend_width = legend_width(&below, &rows, width as i32 - 100)?;
        draw_legend_box(&below, (80, 0), legend_width, &rows)
    }
}

/// Horizontal stacked bars: one bar per method configuration, one segment per pass entry
/// ([`pass_entry`]), the entries of a family ([`pass_family`]) side by side.
struct StackedPassChart {
    caption: String,
    labels: Vec<String>,
    /// `(entry, passes merged into it)`, grouped by family, each family's entries and the
    /// families in order of first appearance.
    entries: Vec<(String, usize)>,
    /// `ms[label][entry]`.
    ms: Vec<Vec<f64>>,
    colors: Colors,
}

impl StackedPassChart {
    /// The chart of `records` (one slice): per label, the mean time of each entry (the sum of
    /// its passes) over the label's records.
    fn new(caption: String, records: &[&Record], colors: &Colors) -> Self {
        // Per family: its entries, each with the pass names merged into it.
        type Entries = Vec<(String, Vec<String>)>;
        let mut families: Vec<(String, Entries)> = Vec::new();
        for p in records.iter().flat_map(|r| &r.passes) {
            let entry = pass_entry(&p.name);
            let family = pass_family(&entry).to_string();
            let i = match families.iter().position(|(f, _)| *f == family) {
                Some(i) => i,
                None => {
                    families.push((family, Vec::new()));
                    families.len() - 1
                }
            };
            let of = &mut families[i].1;
            match of.iter_mut().find(|(e, _)| *e == entry) {
                Some((_, names)) if !names.contains(&p.name) => names.push(p.name.clone()),
                Some(_) => {}
                None => of.push((entry, vec![p.name.clone()])),
            }
        }
        let entries: Vec<(String, usize)> = families
            .into_iter()
            .flat_map(|(_, of)| of.into_iter().map(|(e, names)| (e, names.len())))
            .collect();
        let groups = by_label(records);
        let ms = groups
            .iter()
            .map(|(_, group)| {
                entries
                    .iter()
                    .map(|(entry, _)| {
                        let sums: Vec<f64> = group
                            .iter()
                            .filter_map(|r| {
                                let mut of =
                                    r.passes.iter().filter(|p| pass_entry(&p.name) == *entry);
                                let first = of.next()?.median_ms;
                                Some(first + of.map(|p| p.median_ms).sum::<f64>())
                            })
                            .collect();
                        mean(&sums).unwrap_or(0.0).max(0.0)
                    })
                    .collect()
            })
            .collect();
        Self {
            caption,
            labels: groups.into_iter().map(|(l, _)| l).collect(),
            entries,
            ms,
            colors: colors.clone(),
        }
    }

    /// A heading per family, then a row per entry: its name without the family, with the
    /// number of passes it merges ("analysis (×10)").
    fn legend(&self) -> Vec<LegendRow> {
        let mut rows = Vec::new();
        let mut family = None;
        for (entry, merged) in &self.entries {
            let of = pass_family(entry);
            if family != Some(of) {
                rows.push(LegendRow::new(of, Swatch::Heading));
                family = Some(of);
            }
            let step = entry
                .strip_prefix(of)
                .and_then(|s| s.strip_prefix('.'))
                .unwrap_or(entry);
            let text = if *merged > 1 {
                format!("{step} (×{merged})")
            } else {
                step.to_string()
            };
            rows.push(LegendRow::new(text, Swatch::Block(self.colors.pass(entry))));
        }
        rows
    }
}

impl Chart for StackedPassChart {
    fn points(&self) -> usize {
        self.labels.len()
    }

    fn size(&self) -> (u32, u32) {
        size_for_legend(self.legend().len())
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let area = titled(root, &self.caption, None)?;
        let rows = self.legend();
        let width = area.dim_in_pixel().0 as i32;
        let legend_width = legend_width(&area, &rows, width * 2 / 5)?;
        let (plot, side) = area.split_horizontally(width - legend_width - 20);
        let total = self
            .ms
            .iter()
            .map(|row| row.iter().sum::<f64>())
            .fold(0.0, f64::max);
        // A segmented 0..m range has m + 1 bands, one per label.
        let n = self.labels.len() as i32;
        let longest = self.labels.iter().map(|l| l.len()).max().unwrap_or(0) as u32;
        let mut chart = ChartBuilder::on(&plot)
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size((longest * 8 + 20).clamp(60, 400))
            .build_cartesian_2d(
                0.0..total.max(f64::MIN_POSITIVE) * 1.05,
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
        for (p, (entry, _)) in self.entries.iter().enumerate() {
            let color = self.colors.pass(entry);
            let segments = self.ms.iter().enumerate().map(|(row, times)| {
                let start: f64 = times[..p].iter().sum();
                let y = row as i32;
                [
                    (start, SegmentValue::Exact(y)),
                    (start + times[p], SegmentValue::Exact(y + 1)),
                ]
            });
            // A white outline parts neighbouring segments of similar shades.
            for (corners, style) in
                segments.flat_map(|c| [(c.clone(), color.filled()), (c, WHITE.stroke_width(1))])
            {
                let mut bar = Rectangle::new(corners, style);
                bar.set_margin(6, 6, 0, 0);
                chart.draw_series(std::iter::once(bar))?;
            }
        }
        draw_legend_box(&side, (0, 20), legend_width, &rows)
    }
}

/// One line of a [`LineChart`].
#[derive(Clone, Debug, PartialEq)]
struct Series {
    /// The name in the legend, which picks the color (a method configuration).
    label: String,
    /// The model the points are of, where a chart can show several: each model has its
    /// marker and dash, and no line joins points of two models.
    model: Option<String>,
    pts: Vec<(f64, f64)>,
}

impl Series {
    fn new(label: impl Into<String>, pts: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            model: None,
            pts,
        }
    }
}

/// One line per series; optional horizontal threshold and marked breaking points.
struct LineChart {
    caption: String,
    x_desc: String,
    y_desc: String,
    /// The y axis' floor.
    y_floor: AxisFloor,
    /// Plot x as log10 (labels show the actual value).
    log_x: bool,
    series: Vec<Series>,
    /// `(y, legend)` drawn as a dashed horizontal line.
    threshold: Option<(f64, String)>,
    /// First breaking points `(x, y, label)`, each marked by a cross; one note per point
    /// ("a and b break at 0"), notes stacked so none covers another.
    breaks: Vec<(f64, f64, String)>,
    colors: Colors,
}

impl LineChart {
    /// GPU time per frame against `x_desc`, one line per method configuration (and model).
    fn time(
        caption: String,
        x_desc: &str,
        log_x: bool,
        series: Vec<Series>,
        colors: &Colors,
    ) -> Self {
        Self {
            caption,
            x_desc: x_desc.into(),
            y_desc: "GPU time per frame (ms)".into(),
            y_floor: AxisFloor::NONE,
            log_x,
            series,
            threshold: None,
            breaks: Vec::new(),
            colors: colors.clone(),
        }
    }

    /// The distinct models of the series, in order of first appearance.
    fn models(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for m in self.series.iter().filter_map(|s| s.model.as_deref()) {
            if !out.contains(&m) {
                out.push(m);
            }
        }
        out
    }

    /// How the series of `model` is drawn: by the model's position when there are several.
    fn style_of(&self, model: Option<&str>) -> SeriesStyle {
        let models = self.models();
        let i = model
            .filter(|_| models.len() > 1)
            .and_then(|m| models.iter().position(|n| *n == m));
        SeriesStyle::nth(i.unwrap_or(0))
    }

    /// A row per label; over several models, the labels' colors under "method" and the
    /// models' styles under "model". Then the threshold.
    fn legend(&self) -> Vec<LegendRow> {
        let models = self.models();
        let several = models.len() > 1;
        let mut rows = Vec::new();
        if several {
            rows.push(LegendRow::new("method", Swatch::Heading));
        }
        let mut labels: Vec<&str> = Vec::new();
        for s in &self.series {
            if !labels.contains(&s.label.as_str()) {
                labels.push(&s.label);
                let color = self.colors.label(&s.label);
                let swatch = if several {
                    Swatch::Block(color)
                } else {
                    Swatch::Line(color, SeriesStyle::nth(0))
                };
                rows.push(LegendRow::new(s.label.clone(), swatch));
            }
        }
        if several {
            rows.push(LegendRow::new("model", Swatch::Heading));
            for (i, m) in models.iter().enumerate() {
                let swatch = Swatch::Line(BLACK.to_rgba(), SeriesStyle::nth(i));
                rows.push(LegendRow::new(*m, swatch));
            }
        }
        if let Some((_, text)) = &self.threshold {
            rows.push(LegendRow::new(text.clone(), Swatch::Threshold));
        }
        rows
    }
}

/// The note of methods breaking at `at`: "a breaks at 70", "a, b and c break at 0".
fn break_note(names: &[String], at: f64) -> String {
    match names {
        [] => String::new(),
        [one] => format!("{one} breaks at {at}"),
        [init @ .., last] => format!("{} and {last} break at {at}", init.join(", ")),
    }
}

/// The notes of breaking points `(x, pixel, label)`: one per point, the labels of points at
/// the same x less than 5 pixels apart sharing it. Returns `(pixel, note)`.
fn break_notes(breaks: &[(f64, (i32, i32), String)]) -> Vec<((i32, i32), String)> {
    let mut points: Vec<(f64, (i32, i32), Vec<String>)> = Vec::new();
    for (x, at, label) in breaks {
        match points
            .iter_mut()
            .find(|(px, pat, _)| px == x && (pat.1 - at.1).abs() < 5)
        {
            Some((.., names)) => names.push(label.clone()),
            None => points.push((*x, *at, vec![label.clone()])),
        }
    }
    points
        .into_iter()
        .map(|(x, at, names)| (at, break_note(&names, x)))
        .collect()
}

/// A text box in pixels: left, top, width, height.
type TextBox = (i32, i32, i32, i32);

fn overlap(a: TextBox, b: TextBox) -> bool {
    a.0 < b.0 + b.2 && b.0 < a.0 + a.2 && a.1 < b.1 + b.3 && b.1 < a.1 + a.3
}

/// Tops for the text `boxes` so that no two overlap: taken from the top down, a box meeting
/// one placed before moves past it, down when its top is above `middle`, else up.
fn stack_labels(boxes: &[TextBox], middle: i32) -> Vec<i32> {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by_key(|&i| (boxes[i].1, boxes[i].0));
    let mut placed: Vec<TextBox> = Vec::new();
    let mut tops = vec![0; boxes.len()];
    for i in order {
        let mut b = boxes[i];
        let down = b.1 < middle;
        // Each move passes one placed box for good, so this ends.
        while let Some(hit) = placed.iter().find(|p| overlap(b, **p)) {
            b.1 = if down {
                hit.1 + hit.3 + 2
            } else {
                hit.1 - b.3 - 2
            };
        }
        placed.push(b);
        tops[i] = b.1;
    }
    tops
}

/// Draws `labels` (`(point, text)` in pixels of `root`) beside their points, `dy` below them
/// (negative: above): right of the point, or ending left of it where the text would run past
/// the plot's right edge (`plot`: its pixel ranges). Labels are stacked so that none covers
/// another ([`stack_labels`]); a label moved off its point gets a leader line back to it.
fn draw_labels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    labels: &[((i32, i32), String)],
    dy: i32,
    (xs, ys): (std::ops::Range<i32>, std::ops::Range<i32>),
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let font = legend_font();
    let mut boxes = Vec::new();
    for (p, text) in labels {
        let (w, h) = root.estimate_text_size(text, &font)?;
        // A line of text takes a legend row, whatever its glyphs measure.
        let (w, h) = (w as i32, (h as i32).max(LEGEND_ROW - 2));
        let left = if p.0 + 10 + w > xs.end {
            p.0 - 10 - w
        } else {
            p.0 + 10
        };
        boxes.push((left, p.1 + dy, w, h));
    }
    let tops = stack_labels(&boxes, (ys.start + ys.end) / 2);
    for (((p, text), b), top) in labels.iter().zip(&boxes).zip(tops) {
        if top != b.1 {
            let end = if b.0 > p.0 { b.0 } else { b.0 + b.2 };
            root.draw(&PathElement::new(
                vec![*p, (end, top + b.3 / 2)],
                BLACK.mix(0.5),
            ))?;
        }
        root.draw(&Text::new(text.clone(), (b.0, top), font.clone()))?;
    }
    Ok(())
}

impl Chart for LineChart {
    /// Distinct x values: lines over a single x show nothing.
    fn points(&self) -> usize {
        let mut xs: Vec<u64> = self
            .series
            .iter()
            .flat_map(|s| s.pts.iter().map(|p| p.0.to_bits()))
            .collect();
        xs.sort_unstable();
        xs.dedup();
        xs.len()
    }

    fn size(&self) -> (u32, u32) {
        size_for_legend(self.legend().len())
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
        let all = || self.series.iter().flat_map(|s| s.pts.iter());
        let note = self.y_floor.note(all().map(|p| p.1));
        let area = titled(root, &self.caption, note.as_deref())?;
        let rows = self.legend();
        let width = area.dim_in_pixel().0 as i32;
        let legend_width = legend_width(&area, &rows, width * 2 / 5)?;
        let (plot, side) = area.split_horizontally(width - legend_width - 20);
        let (x0, x1) = padded_range(all().map(|p| tx(p.0)), 0.0);
        let ys = all()
            .map(|p| p.1)
            .chain(self.threshold.as_ref().map(|t| t.0));
        let (y0, y1) = padded_range(ys, self.y_floor.min_span);
        let mut chart = ChartBuilder::on(&plot)
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
        for s in &self.series {
            let color = self.colors.label(&s.label);
            let style = self.style_of(s.model.as_deref());
            let pts: Vec<(f64, f64)> = s.pts.iter().map(|&(x, y)| (tx(x), y)).collect();
            style.line(&mut chart, &pts, color)?;
            style.markers(&mut chart, &pts, color)?;
        }
        if let Some((y, _)) = &self.threshold {
            let dashes = DashedLineSeries::new(vec![(x0, *y), (x1, *y)], 10, 6, BLACK.into());
            chart.draw_series(dashes)?;
        }
        let at: Vec<(f64, (i32, i32), String)> = self
            .breaks
            .iter()
            .map(|(x, y, label)| (*x, chart.backend_coord(&(tx(*x), *y)), label.clone()))
            .collect();
        chart.draw_series(
            self.breaks
                .iter()
                .map(|(x, y, _)| Cross::new((tx(*x), *y), 9, RED.stroke_width(3))),
        )?;
        let notes = break_notes(&at);
        draw_labels(root, &notes, 6, chart.plotting_area().get_pixel_range())?;
        draw_legend_box(&side, (0, 20), legend_width, &rows)
    }
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

/// Per (label, model), in order of first appearance: points sorted by x of the mean frame time
/// over the records sharing `x(record)`. A series never mixes models.
fn time_series(records: &[&Record], x: impl Fn(&Record) -> u64) -> Vec<Series> {
    let mut groups: Vec<((String, String), Vec<&Record>)> = Vec::new();
    for r in records {
        let key = (r.label(), r.model.clone());
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, group)) => group.push(r),
            None => groups.push((key, vec![r])),
        }
    }
    groups
        .into_iter()
        .map(|((label, model), group)| {
            let mut at: BTreeMap<u64, Vec<f64>> = BTreeMap::new();
            for r in group {
                at.entry(x(r)).or_default().push(r.frame_ms_median);
            }
            let pts = at
                .into_iter()
                .filter_map(|(x, ms)| Some((x as f64, mean(&ms)?)))
                .collect();
            Series {
                label,
                model: Some(model),
                pts,
            }
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
            let accuracy: [(&str, &str, MetricFn, AxisFloor); 2] = [
                ("psnr", "PSNR (dB)", |r| r.scores.psnr, AxisFloor::PSNR),
                ("ssim", "SSIM", |r| r.scores.ssim, AxisFloor::SSIM),
            ];
            for (key, desc, metric, floor) in accuracy {
                let chart = ParetoChart {
                    caption: format!("{model} {res}: {desc} vs GPU time, {device}"),
                    y_desc: desc.to_string(),
                    floor,
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
            let chart = StackedPassChart::new(
                format!("{model} {res}: GPU time per pass, {device}"),
                &head,
                &colors,
            );
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
        let mut breaks = Vec::new();
        for s in &curves {
            let mut pts: Vec<(f64, f64)> = s.curve.iter().map(|&(v, h)| (v, h * 100.0)).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            if let Some(v) = s.breaks_at {
                if let Some(&(_, h)) = s.curve.iter().find(|(x, _)| *x == v) {
                    breaks.push((v, h * 100.0, s.label.clone()));
                }
            }
            series.push(Series::new(s.label.clone(), pts));
        }
        let stem = format!("{}_stress_{}", slug(&model), slug(&kind));
        let chart = LineChart {
            caption: format!("{model}: holes vs {kind} stress, {device}"),
            x_desc: unit.clone(),
            y_desc: "hole ratio (%)".into(),
            y_floor: AxisFloor::NONE,
            log_x: false,
            series,
            threshold: Some((
                BREAK_HOLE_RATIO * 100.0,
                format!("breaks above {}%", BREAK_HOLE_RATIO * 100.0),
            )),
            breaks,
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
                Series::new(label, pts)
            })
            .collect();
        let chart = LineChart {
            caption: format!("{model}: PSNR vs {kind} stress, {device}"),
            x_desc: unit,
            y_desc: "PSNR (dB)".into(),
            y_floor: AxisFloor::PSNR,
            log_x: false,
            series,
            threshold: None,
            breaks: Vec::new(),
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
    use crate::eval::results::{PassTiming, REFERENCE_METHOD};

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
        let axes = SpeedAxes::fit(&points, AxisFloor::PSNR);
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
        assert_eq!(padded_range(std::iter::empty(), 0.0), (0.0, 1.0));
        assert_eq!(padded_range([2.0].into_iter(), 0.0), (1.0, 3.0));
        let (lo, hi) = padded_range([0.0, 10.0, f64::NAN].into_iter(), 0.0);
        assert_eq!((lo, hi), (-0.5, 10.5));
    }

    #[test]
    fn a_single_large_value_gets_a_readable_range() {
        // One resolution (256x256 = 65,536 pixels) used to give ticks 65.53k..65.54k.
        let (lo, hi) = padded_range([65_536.0].into_iter(), 0.0);
        assert!((lo - 62_259.2).abs() < 1e-6 && (hi - 68_812.8).abs() < 1e-6);
    }

    #[test]
    fn line_charts_need_two_distinct_x_values() {
        let chart = |xs: &[f64]| LineChart {
            caption: String::new(),
            x_desc: String::new(),
            y_desc: String::new(),
            y_floor: AxisFloor::NONE,
            log_x: false,
            series: vec![
                Series::new("a", xs.iter().map(|&x| (x, 1.0)).collect()),
                Series::new("b", xs.iter().map(|&x| (x, 2.0)).collect()),
            ],
            threshold: None,
            breaks: Vec::new(),
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

    /// The passes of the kernel report: four families, numbered levels included.
    fn kernel_passes() -> Vec<String> {
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
    fn records_with_passes(names: &[String]) -> Vec<Record> {
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
                spread_ms: 0.0,
            });
        }
        out
    }

    /// Draws `chart` into a bitmap of `size` pixels.
    fn draw_at(chart: &impl Chart, size: (u32, u32)) -> DrawResult {
        register_font().unwrap();
        let mut buffer = vec![0u8; size.0 as usize * size.1 as usize * 3];
        let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
        chart.draw(&root)?;
        root.present()?;
        Ok(())
    }

    #[test]
    fn an_accuracy_axis_spans_at_least_its_floor() {
        // The compute report: four PSNRs within 0.06 dB.
        let psnr = [15.014, 15.057, 15.071, 15.071];
        let (lo, hi) = padded_range(psnr.into_iter(), AxisFloor::PSNR.min_span);
        assert!(hi - lo >= 1.0 - 1e-12, "{lo}..{hi}");
        assert!(lo < 15.014 && hi > 15.071);
        let points: Vec<(String, f64, f64)> = psnr
            .iter()
            .enumerate()
            .map(|(i, &p)| (format!("m{i}"), 20.0 + i as f64, p))
            .collect();
        let axes = SpeedAxes::fit(&points, AxisFloor::PSNR);
        assert!(axes.y.1 - axes.y.0 >= 1.0 - 1e-12, "{:?}", axes.y);
        assert_eq!(
            AxisFloor::PSNR.note(psnr.into_iter()).as_deref(),
            Some("all values within 0.06 dB (axis spans at least 1 dB)")
        );
        let (lo, hi) = padded_range([0.9912, 0.9915].into_iter(), AxisFloor::SSIM.min_span);
        assert!(hi - lo >= 0.01 - 1e-12, "{lo}..{hi}");
        assert!(AxisFloor::SSIM.note([0.9912, 0.9915].into_iter()).is_some());
        // Spans beyond the floor are left as they were, and say nothing.
        assert_eq!(
            padded_range([20.0, 25.0].into_iter(), 1.0),
            padded_range([20.0, 25.0].into_iter(), 0.0)
        );
        assert_eq!(AxisFloor::PSNR.note([20.0, 25.0].into_iter()), None);
        assert_eq!(AxisFloor::NONE.note([1.0, 1.0].into_iter()), None);
        assert_eq!(AxisFloor::of_desc("PSNR (dB)"), AxisFloor::PSNR);
        assert_eq!(
            AxisFloor::of_desc("PSNR lost against ε = 0 (dB)"),
            AxisFloor::PSNR
        );
        assert_eq!(AxisFloor::of_desc("SSIM"), AxisFloor::SSIM);
        assert_eq!(AxisFloor::of_desc("frame time (ms)"), AxisFloor::NONE);
    }

    #[test]
    fn passes_group_by_family_and_numbered_passes_share_an_entry() {
        assert_eq!(pass_family("pyramid.analysis.3"), "pyramid");
        assert_eq!(pass_family("compute-hq.resolve"), "compute-hq");
        assert_eq!(pass_family("frame"), "frame");
        assert_eq!(pass_entry("pyramid.analysis.3"), "pyramid.analysis");
        assert_eq!(pass_entry("hpr.round.12"), "hpr.round");
        assert_eq!(pass_entry("kernel.level0"), "kernel.level0");
        assert_eq!(pass_entry("hpr.points.clear"), "hpr.points.clear");
        assert_eq!(pass_entry("frame"), "frame");

        let names = kernel_passes();
        assert_eq!(names.len(), 59);
        let results = Results {
            records: records_with_passes(&names),
            ..Results::default()
        };
        let refs: Vec<&Record> = results.records.iter().collect();
        let chart = StackedPassChart::new(String::new(), &refs, &Colors::new(&results));
        assert_eq!(chart.entries.len(), 24, "{:?}", chart.entries);
        assert!(chart
            .entries
            .contains(&("pyramid.analysis".to_string(), 10)));
        // A family's entries are side by side, so its segments and legend rows are too.
        let families: Vec<&str> = chart.entries.iter().map(|(e, _)| pass_family(e)).collect();
        let mut runs = families.clone();
        runs.dedup();
        assert_eq!(runs, ["mesh", "ewa", "pyramid", "kernel"]);
        let legend = chart.legend();
        assert_eq!(legend.len(), 24 + 4);
        assert!(legend.contains(&LegendRow::new(
            "analysis (×10)",
            Swatch::Block(chart.colors.pass("pyramid.analysis.1"))
        )));
    }

    #[test]
    fn a_pass_family_has_one_hue_and_its_entries_shades_of_it() {
        let names = kernel_passes();
        let results = Results {
            records: records_with_passes(&names),
            ..Results::default()
        };
        let colors = Colors::new(&results);
        let hue_gap = |a: f64, b: f64| {
            let d = (a - b).rem_euclid(360.0);
            d.min(360.0 - d)
        };
        let mut entries: Vec<String> = names.iter().map(|n| pass_entry(n)).collect();
        entries.sort();
        entries.dedup();
        for a in &entries {
            let (ha, ..) = colors.pass_hsl(a);
            for b in &entries {
                let (hb, ..) = colors.pass_hsl(b);
                if a == b {
                    continue;
                }
                if pass_family(a) == pass_family(b) {
                    assert!(hue_gap(ha, hb) <= 12.0, "{a} {ha} vs {b} {hb}");
                } else {
                    assert!(hue_gap(ha, hb) >= 30.0, "{a} {ha} vs {b} {hb}");
                }
                assert_ne!(colors.pass(a), colors.pass(b), "{a} and {b}");
            }
        }
        // The levels of one step share their entry's color.
        assert_eq!(
            colors.pass("kernel.interpolate.0"),
            colors.pass("kernel.interpolate.9")
        );
    }

    #[test]
    fn the_pass_legend_fits_and_the_chart_grows_for_a_long_one() {
        let names = kernel_passes();
        let chart = |names: &[String]| {
            let results = Results {
                records: records_with_passes(names),
                ..Results::default()
            };
            let refs: Vec<&Record> = results.records.iter().collect();
            StackedPassChart::new("passes".into(), &refs, &Colors::new(&results))
        };
        let kernel = chart(&names);
        assert_eq!(kernel.size(), CHART_SIZE);
        draw_at(&kernel, kernel.size()).unwrap();
        // Sixty distinct passes need a taller chart; at the usual size the legend is refused.
        let many: Vec<String> = (0..60).map(|i| format!("f{}.step-{i}", i % 6)).collect();
        let tall = chart(&many);
        assert_eq!(tall.legend().len(), 66);
        assert!(tall.size().1 > CHART_SIZE.1, "{:?}", tall.size());
        draw_at(&tall, tall.size()).unwrap();
        assert!(draw_at(&tall, CHART_SIZE).is_err());
    }

    #[test]
    fn notes_at_one_point_merge_and_the_rest_stack_apart() {
        let at = (100, 50);
        let breaks = [
            (0.0, at, "points".to_string()),
            (0.0, (100, 52), "compute".to_string()),
            (0.0, (100, 49), "points-flat".to_string()),
            (70.0, (600, 400), "affine-flat".to_string()),
        ];
        let notes = break_notes(&breaks);
        assert_eq!(
            notes,
            [
                (at, "points, compute and points-flat break at 0".to_string()),
                ((600, 400), "affine-flat breaks at 70".to_string()),
            ]
        );
        // Three notes at one place (upper half: stacked downwards), two near the bottom
        // (stacked upwards), one on its own: no two boxes overlap, the lone one stays.
        let boxes = [
            (110, 56, 150, 16),
            (110, 56, 150, 16),
            (110, 56, 150, 16),
            (300, 600, 150, 16),
            (320, 604, 150, 16),
            (700, 300, 100, 16),
        ];
        let tops = stack_labels(&boxes, 360);
        let placed: Vec<TextBox> = boxes
            .iter()
            .zip(&tops)
            .map(|(b, &t)| (b.0, t, b.2, b.3))
            .collect();
        for (i, a) in placed.iter().enumerate() {
            for b in &placed[i + 1..] {
                assert!(!overlap(*a, *b), "{a:?} overlaps {b:?}");
            }
        }
        assert!(tops[..3].iter().all(|&t| t >= 56));
        assert!(tops[3..5].iter().all(|&t| t <= 604));
        assert_eq!(tops[5], 300);
    }

    #[test]
    fn time_series_never_join_two_models() {
        let mut records = Vec::new();
        for (model, points, ms) in [
            ("bunny", 35_947, 10.0),
            ("dragon", 437_645, 50.0),
            ("dragon", 5_000_000, 400.0),
        ] {
            let mut r = record("ewa", "", ms, 30.0);
            r.model = model.into();
            r.points = points;
            records.push(r);
        }
        let refs: Vec<&Record> = records.iter().collect();
        let series = time_series(&refs, |r| r.points);
        let keys: Vec<(&str, Option<&str>)> = series
            .iter()
            .map(|s| (s.label.as_str(), s.model.as_deref()))
            .collect();
        assert_eq!(keys, [("ewa", Some("bunny")), ("ewa", Some("dragon"))]);
        assert_eq!(series[0].pts, [(35_947.0, 10.0)]);
        assert_eq!(series[1].pts, [(437_645.0, 50.0), (5_000_000.0, 400.0)]);
        // The chart tells the models apart by style and names them in its legend.
        let chart = LineChart::time(
            "time vs points".into(),
            "points",
            true,
            series,
            &Colors::default(),
        );
        assert_ne!(
            chart.style_of(Some("bunny")),
            chart.style_of(Some("dragon"))
        );
        let legend: Vec<String> = chart.legend().into_iter().map(|r| r.text).collect();
        assert_eq!(legend, ["method", "ewa", "model", "bunny", "dragon"]);
        // Six models keep distinct markers, which tell them apart where no line is drawn.
        let markers: Vec<(Marker, bool)> = (0..6)
            .map(|i| (SeriesStyle::nth(i).marker, SeriesStyle::nth(i).hollow))
            .collect();
        for (i, m) in markers.iter().enumerate() {
            assert!(!markers[i + 1..].contains(m), "{markers:?}");
        }
        draw_at(&chart, chart.size()).unwrap();
    }

    #[test]
    fn stress_charts_draw_methods_breaking_at_one_point() {
        let mut results = Results::default();
        for method in ["points", "compute", "points-flat", "ewa"] {
            for (value, holes) in [(0.0, 0.93), (30.0, 0.92), (60.0, 0.5)] {
                let mut r = record(method, "", 1.0, 10.0);
                r.stress = Some("grazing".into());
                r.stress_value = Some(value);
                r.scores.hole_ratio = Some(if method == "ewa" { 0.0 } else { holes });
                results.records.push(r);
            }
        }
        let dir = std::env::temp_dir().join(format!("surfel_charts_stress_{}", std::process::id()));
        let written = write_charts(&results, &dir).unwrap();
        for stem in ["bunny_stress_grazing_holes", "bunny_stress_grazing_psnr"] {
            assert!(
                written.contains(&dir.join(format!("{stem}.png"))),
                "{written:?}"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

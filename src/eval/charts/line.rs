//! Line charts (time against points, resolution or lights; a metric against stress), with
//! their break notes, and the label placement the speed-vs-accuracy chart shares.

use std::collections::BTreeMap;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::axes::{compact, log_label, log_label_count, mean, padded_range, AxisFloor};
use super::legend::{
    draw_legend_box, legend_font, legend_width, size_for_legend, LegendRow, Swatch, LEGEND_ROW,
};
use super::select::frame_interval;
use super::style::{Colors, SeriesStyle};
use super::{titled, Chart, DrawResult};
use crate::eval::results::Record;

/// One line of a [`LineChart`].
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Series {
    /// The name in the legend, which picks the color (a method configuration).
    label: String,
    /// The model the points are of, where a chart can show several: each model has its
    /// marker and dash, and no line joins points of two models.
    model: Option<String>,
    pts: Vec<(f64, f64)>,
    /// Each point's y interval (a time's bootstrap 95 % interval), drawn as a vertical bar;
    /// empty, or `None` at a point, where there is none.
    pub(super) intervals: Vec<Option<(f64, f64)>>,
}

impl Series {
    pub(super) fn new(label: impl Into<String>, pts: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            model: None,
            pts,
            intervals: Vec::new(),
        }
    }
}

/// Draws an error bar from `a` to `b` (plot coordinates) with a short cap across each end.
pub(super) fn error_bar<DB: DrawingBackend>(
    chart: &mut ChartContext<DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    a: (f64, f64),
    b: (f64, f64),
    color: RGBAColor,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    const CAP: i32 = 5;
    let (pa, pb) = (chart.backend_coord(&a), chart.backend_coord(&b));
    let cap: [(i32, i32); 2] = if (pa.0 - pb.0).abs() < (pa.1 - pb.1).abs() {
        [(-CAP, 0), (CAP, 0)]
    } else {
        [(0, -CAP), (0, CAP)]
    };
    let style = color.stroke_width(2);
    chart.draw_series(std::iter::once(PathElement::new(vec![a, b], style)))?;
    chart.draw_series(
        [a, b]
            .into_iter()
            .map(|end| EmptyElement::at(end) + PathElement::new(cap.to_vec(), style)),
    )?;
    Ok(())
}

/// One line per series; optional horizontal threshold and marked breaking points.
pub(super) struct LineChart {
    pub(super) caption: String,
    pub(super) x_desc: String,
    pub(super) y_desc: String,
    /// The y axis' floor.
    pub(super) y_floor: AxisFloor,
    /// Plot x as log10 (labels show the actual value).
    pub(super) log_x: bool,
    pub(super) series: Vec<Series>,
    /// `(y, legend)` drawn as a dashed horizontal line.
    pub(super) threshold: Option<(f64, String)>,
    /// First breaking points `(x, y, label)`, each marked by a cross; one note per point
    /// ("a and b break at 0"), notes stacked so none covers another.
    pub(super) breaks: Vec<(f64, f64, String)>,
    pub(super) colors: Colors,
}

impl LineChart {
    /// GPU time per frame against `x_desc`, one line per method configuration (and model).
    pub(super) fn time(
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
pub(super) fn draw_labels<DB: DrawingBackend>(
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
        let bounds = self
            .series
            .iter()
            .flat_map(|s| s.intervals.iter().flatten())
            .flat_map(|&(low, high)| [low, high]);
        let ys = all()
            .map(|p| p.1)
            .chain(bounds)
            .chain(self.threshold.as_ref().map(|t| t.0));
        let (y0, y1) = padded_range(ys, self.y_floor.min_span);
        let bars = self
            .series
            .iter()
            .any(|s| s.intervals.iter().any(Option::is_some));
        let y_desc = if bars {
            format!("{} (bars: 95 % CI of the median)", self.y_desc)
        } else {
            self.y_desc.clone()
        };
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
            .y_desc(y_desc)
            .x_label_formatter(&x_fmt)
            .draw()?;
        for s in &self.series {
            let color = self.colors.label(&s.label);
            let style = self.style_of(s.model.as_deref());
            let pts: Vec<(f64, f64)> = s.pts.iter().map(|&(x, y)| (tx(x), y)).collect();
            style.line(&mut chart, &pts, color)?;
            for (&(x, _), interval) in pts.iter().zip(&s.intervals) {
                if let Some((low, high)) = interval {
                    error_bar(&mut chart, (x, *low), (x, *high), color)?;
                }
            }
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

/// Per (label, model), in order of first appearance: points sorted by x of the mean frame time
/// over the records sharing `x(record)`. A series never mixes models.
pub(super) fn time_series(records: &[&Record], x: impl Fn(&Record) -> u64) -> Vec<Series> {
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
            let mut at: BTreeMap<u64, Vec<&Record>> = BTreeMap::new();
            for r in group {
                at.entry(x(r)).or_default().push(r);
            }
            let (pts, intervals) = at
                .into_iter()
                .filter_map(|(x, records)| {
                    let ms: Vec<f64> = records.iter().map(|r| r.frame_ms_median).collect();
                    Some(((x as f64, mean(&ms)?), frame_interval(&records)))
                })
                .unzip();
            Series {
                label,
                model: Some(model),
                pts,
                intervals,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::charts::style::Marker;
    use crate::eval::charts::tests::{draw_at, record};

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
}

//! Colors of method configurations and passes, the styles of a line chart's series, and the
//! embedded font.

use std::collections::BTreeMap;
use std::sync::OnceLock;

use anyhow::{anyhow, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::{pass_entry, pass_family, DrawResult};
use crate::eval::results::{Record, Results};

/// DejaVu Sans (Bitstream Vera license, see `assets/fonts/LICENSE`), used for PNG text.
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

type Plot<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Registers the embedded font as `sans-serif` for plotters' text rendering (once).
pub(super) fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    ok.then_some(())
        .ok_or_else(|| anyhow!("the embedded DejaVu Sans font is invalid"))
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
    pub(super) fn of_labels(mut labels: Vec<String>) -> Self {
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
pub(super) enum Marker {
    Circle,
    Triangle,
    Square,
}

/// How a line chart draws the series of one model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct SeriesStyle {
    pub(super) marker: Marker,
    /// The marker is an outline.
    pub(super) hollow: bool,
    dashed: bool,
}

impl SeriesStyle {
    /// The style of a chart's `i`-th model: six distinct markers (filled, then outlined),
    /// alternately on solid and dashed lines, then again.
    pub(super) fn nth(i: usize) -> Self {
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
    pub(super) fn markers<DB: DrawingBackend>(
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
    pub(super) fn line<DB: DrawingBackend>(
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
    pub(super) fn swatch<DB: DrawingBackend>(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::charts::tests::{kernel_passes, record, records_with_passes};

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
}

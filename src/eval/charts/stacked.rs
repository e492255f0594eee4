//! The per-pass chart: one bar per method configuration, one segment per pass entry.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::axes::mean;
use super::legend::{draw_legend_box, legend_width, size_for_legend, LegendRow, Swatch};
use super::select::by_label;
use super::style::Colors;
use super::{pass_entry, pass_family, titled, Chart, DrawResult};
use crate::eval::results::Record;

/// Horizontal stacked bars: one bar per method configuration, one segment per pass entry
/// ([`pass_entry`]), the entries of a family ([`pass_family`]) side by side.
pub(super) struct StackedPassChart {
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
    pub(super) fn new(caption: String, records: &[&Record], colors: &Colors) -> Self {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::charts::tests::{draw_at, kernel_passes, records_with_passes};
    use crate::eval::charts::CHART_SIZE;
    use crate::eval::results::Results;

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
}

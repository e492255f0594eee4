//! The speed-vs-accuracy chart: a labelled scatter of time and accuracy with its Pareto front.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::axes::{compact, log_label, log_label_count, AxisFloor, SpeedAxes};
use super::legend::{
    draw_legend_box, legend_height, legend_width, size_for_legend, LegendRow, Swatch,
};
use super::line::{draw_labels, error_bar};
use super::style::Colors;
use super::{titled, Chart, DrawResult};
use crate::eval::results::pareto_front;

/// Labelled scatter of (time, accuracy) with its Pareto front as a step line.
pub(super) struct ParetoChart {
    pub(super) caption: String,
    pub(super) y_desc: String,
    /// The accuracy axis' floor.
    pub(super) floor: AxisFloor,
    /// `(label, ms, accuracy)`, without the reference.
    pub(super) points: Vec<(String, f64, f64)>,
    /// Each point's frame-time interval (`select::frame_interval`), drawn as a horizontal
    /// bar; `None` where the records kept no raw samples.
    pub(super) intervals: Vec<Option<(f64, f64)>>,
    /// `(label, ms)` of the reference configurations, named in the legend, not plotted.
    pub(super) references: Vec<(String, f64)>,
    pub(super) colors: Colors,
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
        let mut axes = SpeedAxes::fit(&self.points, self.floor);
        // Bars past the points' range widen the axis, with a 3 % margin.
        let (x0, x1) = axes.x;
        let margin = 0.03 * (x1 - x0);
        for &(low, high) in self.intervals.iter().flatten() {
            axes.x.0 = axes.x.0.min(axes.x_of(low) - margin);
            axes.x.1 = axes.x.1.max(axes.x_of(high) + margin);
        }
        let bars = self.intervals.iter().any(Option::is_some);
        let x_desc = if bars {
            format!("{} (bars: 95 % CI of the median)", axes.x_desc())
        } else {
            axes.x_desc().to_string()
        };
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
            .x_desc(x_desc)
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
        for ((label, _, y), interval) in self.points.iter().zip(&self.intervals) {
            if let Some((low, high)) = interval {
                let color = self.colors.label(label);
                error_bar(
                    &mut chart,
                    (axes.x_of(*low), *y),
                    (axes.x_of(*high), *y),
                    color,
                )?;
            }
        }
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

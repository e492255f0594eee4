//! Axes: the narrowest span of an accuracy axis, the speed-vs-accuracy axes, padded ranges
//! and tick labels.

/// A speed-vs-accuracy chart puts time on a log axis when the slowest plotted time is more
/// than this many times the fastest.
pub const LOG_TIME_RATIO: f64 = 10.0;

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
pub(super) fn padded_range(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
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
pub(super) fn compact(v: f64) -> String {
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
pub(super) fn log_label(v: f64) -> String {
    let step = 10f64.powf(v.floor() - 1.0);
    compact((10f64.powf(v) / step).round() * step)
}

/// Labels to ask for on an x axis spanning `x0..x1`: about one per decade on a log axis.
pub(super) fn log_label_count(log: bool, x0: f64, x1: f64) -> usize {
    if log {
        (x1 - x0).ceil() as usize + 1
    } else {
        10
    }
}

pub(super) fn mean(values: &[f64]) -> Option<f64> {
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
    /// Axes fitting `points` (`(label, ms, accuracy)`, as from
    /// [`speed_accuracy`](super::speed_accuracy), which leaves out the reference): padded
    /// ranges of the finite values, the accuracy range at least `floor` wide, with time on a
    /// log axis when every time is positive and the slowest is more than [`LOG_TIME_RATIO`]
    /// times the fastest.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::charts::tests::record;
    use crate::eval::charts::{reference_times, slug, speed_accuracy};
    use crate::eval::metrics::PSNR_CAP_DB;
    use crate::eval::results::{Record, REFERENCE_METHOD};

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
}

//! Sweep results: one [`Record`] per job, saved as JSON (lossless) and CSV (flat, for
//! spreadsheets), plus the derived views the charts and the report share (labels, Pareto
//! fronts, stability under stress).

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::config::StressKind;
use super::metrics::{Scores, BREAK_HOLE_RATIO};
use super::stats::{median_ci, Estimate};
use super::timing::Invocations;

/// Extracts one metric from a record (`None` when it was not computed).
pub type MetricFn = fn(&Record) -> Option<f64>;

/// The method `surfel bench` renders as the ground truth every method is scored against.
pub const REFERENCE_METHOD: &str = "mesh";

/// (model, stress kind, label) to (value bits to (value, worst hole ratio)).
type StressGroups = BTreeMap<(String, String, String), BTreeMap<u64, (f64, f64)>>;

/// GPU time of one render pass over the measured frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PassTiming {
    pub name: String,
    /// Median over the measured frames, milliseconds.
    pub median_ms: f64,
    /// Interquartile range over the measured frames, milliseconds.
    #[serde(alias = "spread_ms")]
    pub iqr_ms: f64,
    /// Every measured frame's milliseconds, in order (empty in results written before they
    /// were recorded).
    #[serde(default)]
    pub samples_ms: Vec<f64>,
}

/// One row of a sweep: what was rendered, how long it took and how accurate it was.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// Model name (see `ModelSpec::name`).
    pub model: String,
    /// Points rendered.
    pub points: u64,
    pub method: String,
    /// Method parameters as given in the sweep.
    pub params: BTreeMap<String, String>,
    pub width: u32,
    pub height: u32,
    /// Pose name.
    pub pose: String,
    /// The pose's camera distance as a multiple of the default framing's (1 for the default
    /// pose; `None` for eye/target poses and results written before it was recorded).
    #[serde(default)]
    pub distance: Option<f64>,
    pub lights: u32,
    /// Stress kind name (see [`StressKind`]) when a stress was applied.
    pub stress: Option<String>,
    pub stress_value: Option<f64>,
    pub device: String,
    pub driver: String,
    /// Per-pass GPU times in execution order.
    pub passes: Vec<PassTiming>,
    /// Median GPU time of the whole frame, milliseconds.
    pub frame_ms_median: f64,
    /// Interquartile range of the frame time, milliseconds.
    #[serde(alias = "frame_ms_spread")]
    pub frame_ms_iqr: f64,
    /// Every measured frame's GPU milliseconds, in order (empty in results written before
    /// they were recorded).
    #[serde(default)]
    pub frame_samples_ms: Vec<f64>,
    /// A camera-path pose's time of each measured frame (`frame_samples_ms[i]` was rendered at
    /// `path_times[i]`); empty for fixed poses.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub path_times: Vec<f64>,
    /// With the sweep's `pipeline_stats`: each pass's median shader invocations per frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub invocations: Vec<Invocations>,
    /// `points / (frame_ms_median / 1000)`.
    pub points_per_second: f64,
    /// Points projected in the scored frame: for level-of-detail methods the sum of
    /// `projected_per_level`, for every other method the point count (`None` in results
    /// written before it was recorded).
    #[serde(default, alias = "samples")]
    pub projected_points: Option<u64>,
    /// Level-of-detail methods: the scored frame's points projected per level of the object
    /// texture, read back from the GPU (`Renderer::samples_per_level`); empty for other
    /// methods.
    #[serde(default, alias = "samples_per_level")]
    pub projected_per_level: Vec<u64>,
    pub scores: Scores,
}

impl Record {
    /// `method` or `method(key=value, ...)`: the identity of a method configuration in charts
    /// and tables.
    pub fn label(&self) -> String {
        if self.params.is_empty() {
            return self.method.clone();
        }
        let params: Vec<String> = self
            .params
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        format!("{}({})", self.method, params.join(", "))
    }

    /// True for records of the ground-truth method ([`REFERENCE_METHOD`], any parameters):
    /// they score the reference against itself, not a method against it, so the
    /// speed-vs-accuracy charts and Pareto sets leave them out.
    pub fn is_reference(&self) -> bool {
        self.method == REFERENCE_METHOD
    }

    /// Pixels per frame.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// `"WxH"`.
    pub fn resolution(&self) -> String {
        format!("{}x{}", self.width, self.height)
    }

    /// The median frame time with its bootstrap 95 % interval, from the raw samples (`None`
    /// in results written before they were kept).
    pub fn frame_ci(&self) -> Option<Estimate> {
        (!self.frame_samples_ms.is_empty()).then(|| median_ci(&self.frame_samples_ms))
    }
}

/// A whole sweep.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Results {
    /// GPU name.
    pub device: String,
    /// Driver name and version.
    pub driver: String,
    /// When the sweep ran (free-form, e.g. RFC 3339).
    pub created: String,
    pub records: Vec<Record>,
    /// Jobs of the sweep that produced no record, with the reason.
    #[serde(default)]
    pub skipped: Vec<Skipped>,
}

/// A sweep job that was not run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Skipped {
    pub model: String,
    /// Method label with parameters, e.g. `points(size=2)`.
    pub method: String,
    pub width: u32,
    pub height: u32,
    /// `points=N` or `KIND=VALUE` for resampled and stressed jobs, empty otherwise.
    pub variant: String,
    pub reason: String,
}

impl Results {
    /// Writes pretty-printed JSON.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).context("serializing results")?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
    }

    /// Reads results written by [`Results::write_json`].
    pub fn read_json(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }

    /// Writes [`Results::to_csv`].
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.to_csv()).with_context(|| format!("writing {}", path.display()))
    }

    /// Flat CSV (RFC 4180, `\n` line ends), every number a record holds: the fixed columns
    /// (`frames` measured, the frame time's median, interval bounds and IQR),
    /// `projected_points` when any record has it and `projected_points_lN` per level any
    /// record counted, then the scores, then one
    /// `param.KEY` column per parameter key seen in any record (sorted), then
    /// `pass.NAME.median_ms` and `pass.NAME.iqr_ms` per pass name in order of first
    /// appearance, with `pass.NAME.vertex_invocations`, `.fragment_invocations` and
    /// `.compute_invocations` when any record counted them. Missing values are empty cells.
    pub fn to_csv(&self) -> String {
        let param_keys: BTreeSet<&str> = self
            .records
            .iter()
            .flat_map(|r| r.params.keys().map(String::as_str))
            .collect();
        let has_projected = self.records.iter().any(|r| r.projected_points.is_some());
        let levels = self
            .records
            .iter()
            .map(|r| r.projected_per_level.len())
            .max()
            .unwrap_or(0);
        let mut pass_names: Vec<&str> = Vec::new();
        for p in self.records.iter().flat_map(|r| &r.passes) {
            if !pass_names.contains(&p.name.as_str()) {
                pass_names.push(&p.name);
            }
        }
        let has_invocations = self.records.iter().any(|r| !r.invocations.is_empty());
        let mut header: Vec<String> = [
            "model",
            "points",
            "method",
            "width",
            "height",
            "pose",
            "lights",
            "stress",
            "stress_value",
            "device",
            "driver",
            "frames",
            "frame_ms_median",
            "frame_ms_ci_low",
            "frame_ms_ci_high",
            "frame_ms_iqr",
            "points_per_second",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        if has_projected {
            header.push("projected_points".into());
        }
        header.extend((0..levels).map(|l| format!("projected_points_l{l}")));
        header.extend(
            Scores::default()
                .fields()
                .iter()
                .map(|(n, _)| n.to_string()),
        );
        header.extend(param_keys.iter().map(|k| format!("param.{k}")));
        for name in &pass_names {
            header.push(format!("pass.{name}.median_ms"));
            header.push(format!("pass.{name}.iqr_ms"));
            if has_invocations {
                for stage in ["vertex", "fragment", "compute"] {
                    header.push(format!("pass.{name}.{stage}_invocations"));
                }
            }
        }
        let mut out = String::new();
        write_row(&mut out, &header);
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        for r in &self.records {
            let ci = r.frame_ci();
            let mut row = vec![
                r.model.clone(),
                r.points.to_string(),
                r.method.clone(),
                r.width.to_string(),
                r.height.to_string(),
                r.pose.clone(),
                r.lights.to_string(),
                r.stress.clone().unwrap_or_default(),
                opt(r.stress_value),
                r.device.clone(),
                r.driver.clone(),
                r.frame_samples_ms.len().to_string(),
                r.frame_ms_median.to_string(),
                opt(ci.map(|c| c.low)),
                opt(ci.map(|c| c.high)),
                r.frame_ms_iqr.to_string(),
                r.points_per_second.to_string(),
            ];
            if has_projected {
                row.push(
                    r.projected_points
                        .map(|n| n.to_string())
                        .unwrap_or_default(),
                );
            }
            row.extend((0..levels).map(|l| {
                r.projected_per_level
                    .get(l)
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            }));
            row.extend(r.scores.fields().iter().map(|(_, v)| opt(*v)));
            row.extend(
                param_keys
                    .iter()
                    .map(|k| r.params.get(*k).cloned().unwrap_or_default()),
            );
            for name in &pass_names {
                let pass = r.passes.iter().find(|p| p.name == *name);
                row.push(opt(pass.map(|p| p.median_ms)));
                row.push(opt(pass.map(|p| p.iqr_ms)));
                if has_invocations {
                    let counted = r.invocations.iter().find(|i| i.name == *name);
                    row.push(opt(counted.map(|i| i.vertex)));
                    row.push(opt(counted.map(|i| i.fragment)));
                    row.push(opt(counted.map(|i| i.compute)));
                }
            }
            write_row(&mut out, &row);
        }
        out
    }
}

/// Quotes a CSV field when it contains a comma, quote, CR or LF (doubling inner quotes).
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn write_row(out: &mut String, fields: &[String]) {
    let line: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
    let _ = writeln!(out, "{}", line.join(","));
}

/// Indices of the Pareto-optimal points for minimal `x` (time) and maximal `y` (accuracy),
/// sorted by increasing `x`. A point is optimal when no other point is at least as good in
/// both and better in one; of exact duplicates only the first is kept. Non-finite points
/// are ignored.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0.is_finite() && points[i].1.is_finite())
        .collect();
    // Increasing x, and for equal x decreasing y, so the first of each x is its best.
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[b].1.total_cmp(&points[a].1))
            .then(a.cmp(&b))
    });
    let mut front = Vec::new();
    let mut best_y = f64::NEG_INFINITY;
    for i in order {
        if points[i].1 > best_y {
            best_y = points[i].1;
            front.push(i);
        }
    }
    front
}

/// How one method configuration held up along one stress sweep of one model.
#[derive(Clone, Debug, PartialEq)]
pub struct Stability {
    pub model: String,
    /// [`Record::label`].
    pub label: String,
    /// Stress kind name.
    pub kind: String,
    /// `(value, hole ratio)` in order of increasing severity; with several records per value
    /// the worst hole ratio counts.
    pub curve: Vec<(f64, f64)>,
    /// The first value (in severity order) whose hole ratio exceeds [`BREAK_HOLE_RATIO`];
    /// `None` when the method is stable over the whole sweep.
    pub breaks_at: Option<f64>,
}

/// Stability of every (model, label, stress kind) with stress records carrying a hole
/// ratio, sorted by model, kind, then label. Severity order follows
/// [`StressKind::severity_increases_with_value`] (ascending values for unknown kinds).
pub fn stability(results: &Results) -> Vec<Stability> {
    let mut groups: StressGroups = BTreeMap::new();
    for r in &results.records {
        let (Some(kind), Some(value), Some(hole)) =
            (&r.stress, r.stress_value, r.scores.hole_ratio)
        else {
            continue;
        };
        if !value.is_finite() || !hole.is_finite() {
            continue;
        }
        let entry = groups
            .entry((r.model.clone(), kind.clone(), r.label()))
            .or_default()
            .entry(value.to_bits())
            .or_insert((value, hole));
        entry.1 = entry.1.max(hole);
    }
    groups
        .into_iter()
        .map(|((model, kind, label), by_value)| {
            let ascending = kind
                .parse::<StressKind>()
                .map_or(true, StressKind::severity_increases_with_value);
            let mut curve: Vec<(f64, f64)> = by_value.into_values().collect();
            curve.sort_by(|a, b| a.0.total_cmp(&b.0));
            if !ascending {
                curve.reverse();
            }
            let breaks_at = curve
                .iter()
                .find(|(_, h)| *h > BREAK_HOLE_RATIO)
                .map(|(v, _)| *v);
            Stability {
                model,
                label,
                kind,
                curve,
                breaks_at,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(method: &str, size: &str, ms: f64, psnr: f64) -> Record {
        Record {
            model: "bunny".into(),
            points: 1000,
            method: method.into(),
            params: BTreeMap::from([("size".to_string(), size.to_string())]),
            width: 64,
            height: 32,
            pose: "default".into(),
            distance: Some(1.0),
            lights: 1,
            stress: None,
            stress_value: None,
            device: "GPU \"X\", rev 2".into(),
            driver: "1.0".into(),
            passes: vec![PassTiming {
                name: "splat".into(),
                median_ms: ms * 0.75,
                iqr_ms: 0.1,
                samples_ms: Vec::new(),
            }],
            frame_ms_median: ms,
            frame_ms_iqr: 0.2,
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
    fn labels_list_params() {
        let r = record("points", "3", 1.0, 30.0);
        assert_eq!(r.label(), "points(size=3)");
        let bare = Record {
            params: BTreeMap::new(),
            ..r
        };
        assert_eq!(bare.label(), "points");
        assert_eq!(bare.resolution(), "64x32");
        assert_eq!(bare.pixels(), 2048);
    }

    #[test]
    fn csv_quoting() {
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(csv_field("two\nlines"), "\"two\nlines\"");
    }

    #[test]
    fn csv_has_stable_param_and_pass_columns() {
        let mut a = record("points", "1", 2.0, 30.0);
        a.passes.push(PassTiming {
            name: "resolve".into(),
            median_ms: 0.5,
            iqr_ms: 0.0,
            samples_ms: Vec::new(),
        });
        let mut b = record("pyramid", "2", 3.0, 35.0);
        b.params.insert("levels".into(), "4".into());
        b.passes.insert(
            0,
            PassTiming {
                name: "build".into(),
                median_ms: 1.0,
                iqr_ms: 0.0,
                samples_ms: Vec::new(),
            },
        );
        b.stress = Some("noise".into());
        b.stress_value = Some(0.01);
        let results = Results {
            records: vec![a, b],
            ..Results::default()
        };
        let csv = results.to_csv();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        let header: Vec<&str> = lines[0].split(',').collect();
        let tail = &header[header.len() - 8..];
        assert_eq!(
            tail,
            [
                "param.levels",
                "param.size",
                "pass.splat.median_ms",
                "pass.splat.iqr_ms",
                "pass.resolve.median_ms",
                "pass.resolve.iqr_ms",
                "pass.build.median_ms",
                "pass.build.iqr_ms",
            ]
        );
        assert!(lines[1].contains("\"GPU \"\"X\"\", rev 2\""));
        assert!(lines[1].ends_with(",,1,1.5,0.1,0.5,0,,"), "{}", lines[1]);
        assert!(lines[2].contains(",noise,0.01,"));
        assert!(lines[2].ends_with(",4,2,2.25,0.1,,,1,0"), "{}", lines[2]);
        assert_eq!(Results::default().to_csv().lines().count(), 1);
    }

    #[test]
    fn csv_lists_projected_points_and_per_level_counts_only_where_recorded() {
        let plain = |method: &str, projected_points: Option<u64>, per_level: Vec<u64>| Record {
            device: "gpu".into(),
            projected_points,
            projected_per_level: per_level,
            ..record(method, "1", 2.0, 30.0)
        };
        let results = Results {
            records: vec![
                plain("lod-compute", Some(700), vec![400, 200, 100, 0]),
                plain("points", Some(1000), Vec::new()),
            ],
            ..Results::default()
        };
        let csv = results.to_csv();
        let rows: Vec<Vec<&str>> = csv.lines().map(|l| l.split(',').collect()).collect();
        let at = rows[0]
            .iter()
            .position(|c| *c == "projected_points")
            .expect("projected_points column");
        let columns = [
            "projected_points",
            "projected_points_l0",
            "projected_points_l1",
            "projected_points_l2",
            "projected_points_l3",
        ];
        assert_eq!(rows[0][at..at + 5], columns);
        assert_eq!(rows[1][at..at + 5], ["700", "400", "200", "100", "0"]);
        assert_eq!(rows[2][at..at + 5], ["1000", "", "", "", ""]);
        assert!(rows.iter().all(|r| r.len() == rows[0].len()));
        // Results recorded before the samples were have no such columns.
        let old = Results {
            records: vec![plain("points", None, Vec::new())],
            ..Results::default()
        };
        assert!(!old.to_csv().contains("projected"));
    }

    #[test]
    fn records_written_before_samples_were_recorded_still_load() {
        let r = Record {
            projected_points: Some(7),
            projected_per_level: vec![4, 3],
            ..record("lod-compute", "1", 2.0, 30.0)
        };
        let mut json = serde_json::to_value(&r).expect("json");
        let fields = json.as_object_mut().expect("object");
        assert!(fields.remove("projected_points").is_some());
        assert!(fields.remove("projected_per_level").is_some());
        let old: Record = serde_json::from_value(json).expect("an older record loads");
        let expected = Record {
            projected_points: None,
            projected_per_level: Vec::new(),
            ..r.clone()
        };
        assert_eq!(old, expected);
    }

    #[test]
    fn records_with_the_earlier_column_names_load() {
        let r = Record {
            projected_points: Some(7),
            projected_per_level: vec![4, 3],
            ..record("lod-compute", "1", 2.0, 30.0)
        };
        let text = serde_json::to_string(&r)
            .expect("json")
            .replace("\"projected_points\"", "\"samples\"")
            .replace("\"projected_per_level\"", "\"samples_per_level\"")
            .replace("\"frame_ms_iqr\"", "\"frame_ms_spread\"")
            .replace("\"iqr_ms\"", "\"spread_ms\"");
        assert!(text.contains("\"samples\"") && text.contains("\"spread_ms\""));
        let old: Record = serde_json::from_str(&text).expect("an earlier record loads");
        assert_eq!(old, r);
    }

    #[test]
    fn the_csv_gives_each_frame_time_interval_from_its_samples() {
        let samples = vec![2.0, 2.2, 1.9, 2.1, 2.05];
        let r = Record {
            frame_samples_ms: samples.clone(),
            device: "gpu".into(),
            ..record("points", "1", 2.05, 30.0)
        };
        let csv = Results {
            records: vec![r],
            ..Results::default()
        }
        .to_csv();
        let rows: Vec<Vec<&str>> = csv.lines().map(|l| l.split(',').collect()).collect();
        let at = |name: &str| rows[0].iter().position(|c| *c == name).expect(name);
        let ci = median_ci(&samples);
        assert_eq!(rows[1][at("frames")], "5");
        assert_eq!(rows[1][at("frame_ms_ci_low")], ci.low.to_string());
        assert_eq!(rows[1][at("frame_ms_ci_high")], ci.high.to_string());
        assert!(ci.low < 2.05 && ci.high > 2.0, "{ci:?}");
        assert_eq!(rows[0].iter().filter(|c| c.contains("samples")).count(), 0);
    }

    #[test]
    fn pareto_front_is_known() {
        let pts = [
            (1.0, 20.0),      // 0: fastest
            (2.0, 25.0),      // 1: front
            (2.0, 22.0),      // 2: same time, worse
            (3.0, 24.0),      // 3: dominated by 1
            (4.0, 30.0),      // 4: front
            (5.0, 30.0),      // 5: slower, equal
            (f64::NAN, 99.0), // ignored
            (1.0, 20.0),      // duplicate of 0
        ];
        assert_eq!(pareto_front(&pts), vec![0, 1, 4]);
        assert!(pareto_front(&[]).is_empty());
    }

    #[test]
    fn stability_finds_the_first_breaking_value_in_severity_order() {
        let stressed = |method: &str, kind: &str, value: f64, hole: f64| Record {
            stress: Some(kind.into()),
            stress_value: Some(value),
            scores: Scores {
                hole_ratio: Some(hole),
                ..Scores::default()
            },
            ..record(method, "1", 1.0, 30.0)
        };
        let results = Results {
            records: vec![
                stressed("a", "subsample", 1.0, 0.0),
                stressed("a", "subsample", 0.1, 0.05),
                stressed("a", "subsample", 0.5, 0.02),
                stressed("a", "subsample", 0.5, 0.001),
                stressed("b", "grazing", 0.0, 0.0),
                stressed("b", "grazing", 85.0, 0.005),
                record("c", "1", 1.0, 30.0),
            ],
            ..Results::default()
        };
        let s = stability(&results);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].kind, "grazing");
        assert_eq!(s[0].breaks_at, None);
        assert_eq!(s[1].label, "a(size=1)");
        assert_eq!(s[1].curve, vec![(1.0, 0.0), (0.5, 0.02), (0.1, 0.05)]);
        assert_eq!(s[1].breaks_at, Some(0.5));
    }
}

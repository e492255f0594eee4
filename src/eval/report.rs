//! The markdown report of a sweep: results tables, Pareto sets, stability under stress and
//! the charts.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use anyhow::{Context, Result};

use super::charts::{model_slices, models, reference_times, speed_accuracy, write_charts_by_model};
use super::metrics::{BREAK_HOLE_RATIO, PSNR_CAP_DB};
use super::results::{pareto_front, stability, MetricFn, Record, Results};

/// Subdirectory of the report's directory that holds its charts.
pub const CHARTS_DIR: &str = "charts";

/// Writes `out_dir/report.md` and the charts it embeds (via
/// [`crate::eval::charts::write_charts`], into `out_dir/charts/`, overwriting charts already
/// written there) and returns the report's path. `results_path` is linked from the header,
/// relative to `out_dir` where possible, and so is the CSV beside it (else `out_dir`'s).
pub fn write_report(results: &Results, results_path: &Path, out_dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let charts = write_charts_by_model(results, &out_dir.join(CHARTS_DIR))?;
    let lod = super::lod::section(results, out_dir, &out_dir.join(CHARTS_DIR))?;
    let csv = Some(results_path.with_extension("csv"))
        .filter(|c| c.is_file())
        .unwrap_or_else(|| out_dir.join("results.csv"));
    let links = Links {
        json: relative_link(results_path, out_dir),
        csv: csv.is_file().then(|| relative_link(&csv, out_dir)),
    };
    let mut text = render(results, &links, &charts, out_dir);
    text.push_str(&lod);
    let path = out_dir.join("report.md");
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// `path` relative to `base` when both resolve (e.g. `../results.json`), else `path` as is,
/// with `/` separators for markdown.
fn relative_link(path: &Path, base: &Path) -> String {
    let resolved = (path.canonicalize(), base.canonicalize());
    let rel = match resolved {
        (Ok(p), Ok(b)) => {
            let (pc, bc): (Vec<Component>, Vec<Component>) =
                (p.components().collect(), b.components().collect());
            let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
            let mut rel = PathBuf::new();
            for _ in common..bc.len() {
                rel.push("..");
            }
            for c in &pc[common..] {
                rel.push(c);
            }
            rel
        }
        _ => path.to_path_buf(),
    };
    rel.to_string_lossy().replace('\\', "/")
}

/// Escapes a table cell.
fn cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

/// One dimension of a configuration, as a table shows it.
type Dimension = fn(&Record) -> String;

/// Renders a metric value for a table cell.
type Formatter = fn(Option<f64>) -> String;

fn fmt_opt(v: Option<f64>, decimals: usize, scale: f64) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{:.*}", decimals, v * scale),
        _ => "–".into(),
    }
}

fn fmt_psnr(v: Option<f64>) -> String {
    match v {
        Some(v) if v >= PSNR_CAP_DB => format!("≥{PSNR_CAP_DB:.0}"),
        other => fmt_opt(other, 2, 1.0),
    }
}

/// The report's links to the results: the JSON, and the CSV beside it when there is one.
struct Links {
    json: String,
    csv: Option<String>,
}

fn render(
    results: &Results,
    links: &Links,
    charts: &[(Option<String>, PathBuf)],
    out_dir: &Path,
) -> String {
    let mut md = String::new();
    let or_unknown = |s: &str| {
        if s.is_empty() {
            "unknown".to_string()
        } else {
            s.to_string()
        }
    };
    let _ = writeln!(md, "# surfel evaluation report\n");
    let _ = writeln!(md, "- Device: {}", or_unknown(&results.device));
    let _ = writeln!(md, "- Driver: {}", or_unknown(&results.driver));
    let _ = writeln!(md, "- Date: {}", or_unknown(&results.created));
    let _ = writeln!(md, "- Results: [{0}]({0})", links.json);
    if let Some(csv) = &links.csv {
        let _ = writeln!(
            md,
            "- Every number of every record (per-pass times, IQR, throughput, IoU, boundary, \
             depth, flicker, points projected): [{csv}]({csv})"
        );
    }
    let _ = writeln!(
        md,
        "- Records: {}; jobs skipped: {}\n",
        results.records.len(),
        results.skipped.len()
    );
    if results.records.is_empty() {
        let _ = writeln!(md, "No records.\n");
        skipped_section(&mut md, results);
        return md;
    }
    let chart_link = |path: &PathBuf| {
        path.strip_prefix(out_dir)
            .unwrap_or(path)
            .to_string_lossy()
            .replace('\\', "/")
    };
    let embed = |md: &mut String, model: Option<&str>| {
        for (_, path) in charts
            .iter()
            .filter(|(m, p)| m.as_deref() == model && p.extension().is_some_and(|e| e == "png"))
        {
            let link = chart_link(path);
            let svg = link.trim_end_matches(".png").to_string() + ".svg";
            let name = path.file_stem().unwrap_or_default().to_string_lossy();
            let _ = writeln!(md, "![{name}]({link}) ([SVG]({svg}))\n");
        }
    };
    for model in models(results) {
        let _ = writeln!(md, "## Model `{model}`\n");
        model_table(&mut md, results, &model);
        path_table(&mut md, results, &model);
        pareto_section(&mut md, results, &model);
        embed(&mut md, Some(&model));
    }
    cost_section(&mut md, results);
    stability_section(&mut md, results);
    if charts.iter().any(|(m, _)| m.is_none()) {
        let _ = writeln!(md, "## Cross-model charts\n");
        embed(&mut md, None);
    }
    skipped_section(&mut md, results);
    md
}

/// The jobs that produced no record, with the reason.
fn skipped_section(md: &mut String, results: &Results) {
    if results.skipped.is_empty() {
        return;
    }
    let _ = writeln!(md, "## Skipped jobs\n");
    let _ = writeln!(md, "| model | method | resolution | variant | reason |");
    let _ = writeln!(md, "|---|---|---|---|---|");
    for s in &results.skipped {
        let _ = writeln!(
            md,
            "| {} | {} | {}x{} | {} | {} |",
            cell(&s.model),
            cell(&s.method),
            s.width,
            s.height,
            if s.variant.is_empty() {
                "–".to_string()
            } else {
                cell(&s.variant)
            },
            cell(&s.reason)
        );
    }
    let _ = writeln!(md);
}

/// The model's unstressed records as the compact table: one row per configuration (the
/// method and, where the rows differ in them, resolution, points, pose and lights; what all
/// rows share is said above the table), its median frame time with the bootstrap 95 %
/// interval, PSNR, SSIM and holes. Every other number (per-pass times, IQR, throughput, IoU,
/// boundary, depth, flicker, points projected) is in the results CSV.
fn model_table(md: &mut String, results: &Results, model: &str) {
    let mut rows: Vec<&Record> = results
        .records
        .iter()
        .filter(|r| r.model == model && r.stress.is_none())
        .collect();
    if rows.is_empty() {
        let _ = writeln!(md, "No unstressed records.\n");
        return;
    }
    rows.sort_by(|a, b| {
        (a.pixels(), a.points, &a.pose, a.lights, a.label()).cmp(&(
            b.pixels(),
            b.points,
            &b.pose,
            b.lights,
            b.label(),
        ))
    });
    let dimensions: [(&str, Dimension); 4] = [
        ("resolution", Record::resolution),
        ("points", |r| r.points.to_string()),
        ("pose", |r| r.pose.clone()),
        ("lights", |r| r.lights.to_string()),
    ];
    let (varying, shared): (Vec<_>, Vec<_>) = dimensions
        .iter()
        .partition(|(_, of)| rows.iter().any(|r| of(r) != of(rows[0])));
    let shared: Vec<String> = shared
        .iter()
        .map(|(name, of)| format!("{name} {}", of(rows[0])))
        .collect();
    let _ = writeln!(md, "All rows: {}.\n", cell(&shared.join(", ")));
    let _ = writeln!(
        md,
        "| configuration | frame ms [95 % CI] | PSNR dB | SSIM | hole % |\n|---|---|---|---|---|"
    );
    for r in rows {
        let mut configuration = vec![r.label()];
        configuration.extend(varying.iter().map(|(name, of)| format!("{name} {}", of(r))));
        let s = &r.scores;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            cell(&configuration.join(", ")),
            frame_ms(r),
            fmt_psnr(s.psnr),
            fmt_opt(s.ssim, 4, 1.0),
            fmt_opt(s.hole_ratio, 2, 100.0),
        );
    }
    let _ = writeln!(md);
}

/// The model's records timed along a camera path: per path pose and configuration, the
/// frames, the median frame time and the slowest frame with its path time (the chart of
/// each path shows every frame).
fn path_table(md: &mut String, results: &Results, model: &str) {
    let rows: Vec<&Record> = results
        .records
        .iter()
        .filter(|r| r.model == model && r.stress.is_none() && !r.path_times.is_empty())
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "### Along camera paths\n\n| pose | configuration | frames | frame ms [95 % CI] | \
         slowest frame ms | at path time |\n|---|---|---|---|---|---|"
    );
    for r in rows {
        let slowest = r
            .frame_samples_ms
            .iter()
            .zip(&r.path_times)
            .max_by(|a, b| a.0.total_cmp(b.0));
        let (ms, at) = slowest.map_or(("–".into(), "–".into()), |(ms, t)| {
            (format!("{ms:.3}"), format!("{t:.3}"))
        });
        let _ = writeln!(
            md,
            "| {} | {}, {}, points {}, lights {} | {} | {} | {ms} | {at} |",
            cell(&r.pose),
            cell(&r.label()),
            r.resolution(),
            r.points,
            r.lights,
            r.frame_samples_ms.len(),
            frame_ms(r),
        );
    }
    let _ = writeln!(md);
}

/// `median [low, high]` from the record's raw frame times, or the median alone in results
/// written before they were kept.
fn frame_ms(r: &Record) -> String {
    match r.frame_ci() {
        Some(ci) => format!("{:.3} [{:.3}, {:.3}]", ci.value, ci.low, ci.high),
        None => format!("{:.3}", r.frame_ms_median),
    }
}

fn pareto_section(md: &mut String, results: &Results, model: &str) {
    for head in model_slices(results, model) {
        pareto_tables(md, &head);
    }
}

fn pareto_tables(md: &mut String, head: &[&Record]) {
    let Some(first) = head.first() else {
        return;
    };
    let accuracy: [(&str, MetricFn, Formatter); 2] = [
        ("PSNR dB", |r| r.scores.psnr, fmt_psnr),
        ("SSIM", |r| r.scores.ssim, |v| fmt_opt(v, 4, 1.0)),
    ];
    for (name, metric, fmt) in accuracy {
        let pts = speed_accuracy(head, metric);
        if pts.is_empty() {
            continue;
        }
        let xy: Vec<(f64, f64)> = pts.iter().map(|p| (p.1, p.2)).collect();
        let _ = writeln!(
            md,
            "### Pareto set: GPU time vs {name} ({}, {} points)\n",
            first.resolution(),
            first.points
        );
        let _ = writeln!(md, "| method | frame ms | {name} |\n|---|---|---|");
        for i in pareto_front(&xy) {
            let (label, ms, acc) = &pts[i];
            let _ = writeln!(md, "| {} | {ms:.3} | {} |", cell(label), fmt(Some(*acc)));
        }
        let _ = writeln!(md);
        for (label, ms) in reference_times(head) {
            let _ = writeln!(md, "Reference (not ranked): `{label}`, {ms:.3} ms.\n");
        }
    }
}

/// The cost ratios 002 and 000 discuss, where the sweep has both sides (median over the
/// baseline records of each side, per model, point count, resolution and light count):
/// blended shadings against flat for each splat rasterization, EWA against perspective
/// deferred splats, and each method at its largest light count against its smallest.
pub fn cost_ratios(results: &Results) -> Vec<(String, String, f64)> {
    type Key = (String, u64, (u32, u32));
    let mut times: BTreeMap<(Key, String, u32), Vec<f64>> = BTreeMap::new();
    for r in results.records.iter().filter(|r| r.stress.is_none()) {
        let key = (r.model.clone(), r.points, (r.width, r.height));
        times
            .entry((key, r.method.clone(), r.lights))
            .or_default()
            .push(r.frame_ms_median);
    }
    let median = |v: &[f64]| {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let slice =
        |(m, p, (w, h)): &Key, lights: u32| format!("{m}, {p} points, {w}x{h}, {lights} light(s)");
    let mut out = Vec::new();
    let pairs = times
        .keys()
        .map(|(k, m, l)| (k.clone(), m.clone(), *l))
        .collect::<Vec<_>>();
    for (key, method, lights) in &pairs {
        let at = |m: &str| {
            times
                .get(&(key.clone(), m.to_string(), *lights))
                .map(|v| median(v))
        };
        let t = at(method).unwrap_or(f64::NAN);
        for shading in ["gouraud", "phong", "deferred"] {
            if let Some(raster) = method.strip_suffix(&format!("-{shading}")) {
                if let Some(flat) = at(&format!("{raster}-flat")) {
                    out.push((
                        slice(key, *lights),
                        format!("{method} / {raster}-flat"),
                        t / flat,
                    ));
                }
            }
        }
        if method == "ewa" {
            if let Some(deferred) = at("perspective-deferred") {
                out.push((
                    slice(key, *lights),
                    "ewa / perspective-deferred".into(),
                    t / deferred,
                ));
            }
        }
    }
    // The smallest and largest light count of each (slice, method).
    let mut range: BTreeMap<(Key, String), (u32, u32)> = BTreeMap::new();
    for (key, method, lights) in &pairs {
        let r = range
            .entry((key.clone(), method.clone()))
            .or_insert((*lights, *lights));
        *r = (r.0.min(*lights), r.1.max(*lights));
    }
    for ((key, method), (lo, hi)) in range.into_iter().filter(|(_, (lo, hi))| lo < hi) {
        let t = |l: u32| median(&times[&(key.clone(), method.clone(), l)]);
        let (m, p, (w, h)) = &key;
        out.push((
            format!("{m}, {p} points, {w}x{h}"),
            format!("{method}: {hi} lights / {lo}"),
            t(hi) / t(lo),
        ));
    }
    out
}

fn cost_section(md: &mut String, results: &Results) {
    let ratios = cost_ratios(results);
    if ratios.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## Cost ratios\n\nFrame time of the first configuration over the second (median \
         frame times, same model, points, resolution and lights).\n\n| slice | ratio | value |\n|---|---|---|"
    );
    for (slice, what, value) in ratios {
        let _ = writeln!(md, "| {} | {} | {value:.2} |", cell(&slice), cell(&what));
    }
    let _ = writeln!(md);
}

fn stability_section(md: &mut String, results: &Results) {
    let stab = stability(results);
    if stab.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## Stability under stress\n\nFirst stress value (in order of increasing severity) at \
         which the hole ratio exceeds {}%, or \"stable\" over the values tested.\n",
        BREAK_HOLE_RATIO * 100.0
    );
    let mut by_model: BTreeMap<&str, Vec<_>> = BTreeMap::new();
    for s in &stab {
        by_model.entry(s.model.as_str()).or_default().push(s);
    }
    for (model, entries) in by_model {
        let mut kinds: Vec<&str> = entries.iter().map(|s| s.kind.as_str()).collect();
        kinds.sort_unstable();
        kinds.dedup();
        let mut labels: Vec<&str> = entries.iter().map(|s| s.label.as_str()).collect();
        labels.sort_unstable();
        labels.dedup();
        let _ = writeln!(md, "### `{model}`\n");
        let _ = writeln!(md, "| method | {} |", kinds.join(" | "));
        let _ = writeln!(md, "|{}", "---|".repeat(kinds.len() + 1));
        for label in labels {
            let cells: Vec<String> = kinds
                .iter()
                .map(
                    |kind| match entries.iter().find(|s| s.label == label && s.kind == *kind) {
                        Some(s) => match s.breaks_at {
                            Some(v) => format!("breaks at {v}"),
                            None => "stable".into(),
                        },
                        None => "–".into(),
                    },
                )
                .collect();
            let _ = writeln!(md, "| {} | {} |", cell(label), cells.join(" | "));
        }
        let _ = writeln!(md);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_links_and_cells() {
        let dir = std::env::temp_dir().join(format!("surfel_report_rel_{}", std::process::id()));
        let out = dir.join("out");
        std::fs::create_dir_all(&out).unwrap();
        let file = dir.join("results.json");
        std::fs::write(&file, "{}").unwrap();
        assert_eq!(relative_link(&file, &out), "../results.json");
        assert_eq!(
            relative_link(Path::new("missing.json"), &out),
            "missing.json"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(cell("a|b"), "a\\|b");
        assert_eq!(fmt_psnr(Some(100.0)), "≥100");
        assert_eq!(fmt_opt(Some(0.0123), 2, 100.0), "1.23");
        assert_eq!(fmt_opt(None, 2, 1.0), "–");
    }

    #[test]
    fn the_model_table_names_what_varies_and_gives_the_interval() {
        let base = Record {
            model: "m".into(),
            points: 1000,
            method: "points".into(),
            params: BTreeMap::from([("size".to_string(), "2".to_string())]),
            width: 8,
            height: 8,
            pose: "p".into(),
            distance: None,
            lights: 1,
            stress: None,
            stress_value: None,
            device: String::new(),
            driver: String::new(),
            passes: Vec::new(),
            frame_ms_median: 2.0,
            frame_ms_iqr: 0.0,
            frame_samples_ms: Vec::new(),
            path_times: Vec::new(),
            invocations: Vec::new(),
            points_per_second: 1e6,
            projected_points: None,
            projected_per_level: Vec::new(),
            scores: crate::eval::metrics::Scores {
                psnr: Some(31.234),
                ssim: Some(0.91),
                hole_ratio: Some(0.0125),
                ..Default::default()
            },
        };
        let samples = vec![1.0, 1.2, 0.9, 1.1, 1.0, 1.3, 0.95];
        let sampled = Record {
            method: "splat".into(),
            params: BTreeMap::new(),
            lights: 4,
            frame_samples_ms: samples.clone(),
            frame_ms_median: crate::eval::stats::median(&samples),
            ..base.clone()
        };
        let mut md = String::new();
        let results = Results {
            records: vec![sampled, base],
            ..Default::default()
        };
        model_table(&mut md, &results, "m");
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines[0], "All rows: resolution 8x8, points 1000, pose p.");
        assert_eq!(
            lines[2],
            "| configuration | frame ms [95 % CI] | PSNR dB | SSIM | hole % |"
        );
        assert_eq!(
            lines[4],
            "| points(size=2), lights 1 | 2.000 | 31.23 | 0.9100 | 1.25 |"
        );
        let ci = crate::eval::stats::median_ci(&samples);
        assert_eq!(
            lines[5],
            format!(
                "| splat, lights 4 | 1.000 [{:.3}, {:.3}] | 31.23 | 0.9100 | 1.25 |",
                ci.low, ci.high
            )
        );
        assert!(
            ci.low <= 1.0 && ci.high >= 1.0 && ci.high > ci.low,
            "{ci:?}"
        );
        assert_eq!(lines[6], "");
        assert_eq!(lines.len(), 7);
    }

    #[test]
    fn empty_results_give_a_short_report() {
        let dir = std::env::temp_dir().join(format!("surfel_report_empty_{}", std::process::id()));
        let path = write_report(&Results::default(), Path::new("r.json"), &dir).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("No records."));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn cost_ratios_pair_shadings_ewa_and_light_counts() {
        let record = |method: &str, lights: u32, ms: f64| Record {
            model: "m".into(),
            points: 10,
            method: method.into(),
            params: BTreeMap::new(),
            width: 8,
            height: 8,
            pose: "p".into(),
            distance: None,
            lights,
            stress: None,
            stress_value: None,
            device: String::new(),
            driver: String::new(),
            passes: Vec::new(),
            frame_ms_median: ms,
            frame_ms_iqr: 0.0,
            frame_samples_ms: Vec::new(),
            path_times: Vec::new(),
            invocations: Vec::new(),
            points_per_second: 0.0,
            projected_points: None,
            projected_per_level: Vec::new(),
            scores: Default::default(),
        };
        let results = Results {
            records: vec![
                record("affine-flat", 1, 10.0),
                record("affine-gouraud", 1, 15.0),
                record("affine-deferred", 1, 20.0),
                record("affine-deferred", 16, 24.0),
                record("perspective-deferred", 1, 40.0),
                record("ewa", 1, 10.0),
                record("points", 1, 3.0),
            ],
            ..Default::default()
        };
        let ratios = cost_ratios(&results);
        let find = |what: &str| {
            ratios
                .iter()
                .find(|r| r.1 == what)
                .map(|r| r.2)
                .unwrap_or_else(|| panic!("{what} missing from {ratios:?}"))
        };
        assert_eq!(find("affine-gouraud / affine-flat"), 1.5);
        assert_eq!(find("affine-deferred / affine-flat"), 2.0);
        assert_eq!(find("ewa / perspective-deferred"), 0.25);
        assert_eq!(find("affine-deferred: 16 lights / 1"), 1.2);
        assert_eq!(ratios.len(), 4, "{ratios:?}");
    }
}

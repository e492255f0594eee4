//! The level-of-detail part of a report (thesis 000 ch. 7): samples projected, frame
//! time and accuracy against the camera distance (every method, so with and without level of
//! detail), the accuracy lost against ε, frame time and accuracy against the point budget,
//! and frame time against the geometry path's vertices per invocation; each drawn when the
//! results vary that quantity.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context as _, Result};

use super::charts::write_line_chart;
use super::results::{Record, Results};

/// Accuracy loss the default ε may cost (000 ch. 7), dB of PSNR against ε = 0.
pub const LOSS_DB: f64 = 0.5;

/// PSNR above which a loss is not visible: the customary threshold of visually lossless
/// image coding. Where ε = 0 already scores above it (far views, sub-pixel samples), the
/// default ε may lose more than `LOSS_DB` while the image stays above it.
pub const LOSSLESS_DB: f64 = 40.0;

type Series = Vec<(String, Vec<(f64, f64)>)>;

/// A charted metric: file key, axis description, value.
type Metric = (&'static str, &'static str, fn(&Record) -> Option<f64>);

fn is_lod(r: &Record) -> bool {
    crate::methods::find(&r.method).is_ok_and(|m| m.needs_lod)
}

fn param(r: &Record, name: &str) -> Option<f64> {
    r.params.get(name).and_then(|v| v.parse().ok())
}

/// The record's configuration without parameter `x`: `method` or `method(k=v, ...)`.
fn label_without(r: &Record, x: &str) -> String {
    let params: Vec<String> = r
        .params
        .iter()
        .filter(|(k, _)| k.as_str() != x)
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    if params.is_empty() {
        r.method.clone()
    } else {
        format!("{}({})", r.method, params.join(", "))
    }
}

/// The records' slices: model, points and resolution.
fn slices(results: &Results) -> BTreeMap<(String, u64, String), Vec<&Record>> {
    let mut out: BTreeMap<_, Vec<&Record>> = BTreeMap::new();
    for r in results.records.iter().filter(|r| r.stress.is_none()) {
        out.entry((r.model.clone(), r.points, r.resolution()))
            .or_default()
            .push(r);
    }
    out
}

/// `series` with each series' points sorted by x, without series of fewer than two points.
fn sorted(series: BTreeMap<String, Vec<(f64, f64)>>) -> Series {
    series
        .into_iter()
        .filter(|(_, pts)| pts.len() >= 2)
        .map(|(name, mut pts)| {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            (name, pts)
        })
        .collect()
}

/// A table cell: samples projected / frame ms / PSNR dB.
fn cell(r: &Record) -> String {
    format!(
        "{} / {:.1} / {}",
        r.projected_points.map_or("–".into(), |s| s.to_string()),
        r.frame_ms_median,
        r.scores.psnr.map_or("–".into(), |p| format!("{p:.2}"))
    )
}

/// Writes a line chart (`write_line_chart`) into `charts_dir` and embeds it in `md`.
fn chart(
    md: &mut String,
    (out_dir, charts_dir): (&Path, &Path),
    (stem, caption): (&str, &str),
    axes: (&str, &str),
    log_x: bool,
    series: BTreeMap<String, Vec<(f64, f64)>>,
) -> Result<()> {
    let paths = write_line_chart(charts_dir, stem, caption, axes, log_x, sorted(series))?;
    embed(md, &paths, out_dir);
    Ok(())
}

fn embed(md: &mut String, paths: &[std::path::PathBuf], out_dir: &Path) {
    for path in paths
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
    {
        let link = path
            .strip_prefix(out_dir)
            .unwrap_or(path)
            .to_string_lossy()
            .replace('\\', "/");
        let svg = link.trim_end_matches(".png").to_string() + ".svg";
        let name = path.file_stem().unwrap_or_default().to_string_lossy();
        let _ = writeln!(md, "![{name}]({link}) ([SVG]({svg}))\n");
    }
}

fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// The level-of-detail section of the report for `results` (empty without level-of-detail
/// records), its charts written into `charts_dir` (inside `out_dir`).
pub fn section(results: &Results, out_dir: &Path, charts_dir: &Path) -> Result<String> {
    let mut md = String::new();
    if !results.records.iter().any(is_lod) {
        return Ok(md);
    }
    std::fs::create_dir_all(charts_dir)
        .with_context(|| format!("creating {}", charts_dir.display()))?;
    let device = &results.device;
    let _ = writeln!(md, "## Level of detail\n");
    for ((model, points, res), records) in slices(results) {
        let stem = slug(&format!("lod_{model}_{points}_{res}"));
        let title = format!("{model} ({points} points) {res}");
        distance_part(
            &mut md,
            &records,
            (&stem, &title, device),
            out_dir,
            charts_dir,
        )?;
        epsilon_part(
            &mut md,
            &records,
            (&stem, &title, device),
            out_dir,
            charts_dir,
        )?;
        for (name, what) in [
            ("budget", "point budget (samples)"),
            ("chunk", "vertices per geometry invocation"),
        ] {
            param_part(
                &mut md,
                &records,
                (name, what),
                (&stem, &title, device),
                out_dir,
                charts_dir,
            )?;
        }
    }
    Ok(md)
}

/// Samples, frame time and PSNR against camera distance, a series per configuration.
fn distance_part(
    md: &mut String,
    records: &[&Record],
    (stem, title, device): (&str, &str, &str),
    out_dir: &Path,
    charts_dir: &Path,
) -> Result<()> {
    let mut distances: Vec<f64> = records.iter().filter_map(|r| r.distance).collect();
    distances.sort_by(f64::total_cmp);
    distances.dedup();
    if distances.len() < 2 {
        return Ok(());
    }
    let metrics: [Metric; 3] = [
        ("samples", "samples projected", |r| {
            r.projected_points.map(|s| s as f64)
        }),
        ("ms", "frame time (ms)", |r| Some(r.frame_ms_median)),
        ("psnr", "PSNR (dB)", |r| r.scores.psnr),
    ];
    let _ = writeln!(md, "### {title}: against camera distance\n");
    let _ = writeln!(
        md,
        "Distance as a multiple of the default framing's. Cells: samples projected / frame \
         ms / PSNR dB.\n"
    );
    let mut rows: BTreeMap<String, BTreeMap<u64, String>> = BTreeMap::new();
    for r in records.iter().filter(|r| r.distance.is_some()) {
        rows.entry(r.label())
            .or_default()
            .insert(r.distance.unwrap_or_default().to_bits(), cell(r));
    }
    let _ = write!(md, "| configuration |");
    for d in &distances {
        let _ = write!(md, " {d} |");
    }
    let _ = writeln!(md, "\n|---|{}", "---|".repeat(distances.len()));
    for (label, cells) in &rows {
        let _ = write!(md, "| {label} |");
        for d in &distances {
            let _ = write!(
                md,
                " {} |",
                cells.get(&d.to_bits()).map_or("–", String::as_str)
            );
        }
        let _ = writeln!(md);
    }
    let _ = writeln!(md);
    for (key, desc, metric) in metrics {
        let mut series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
        for r in records {
            if let (Some(d), Some(y)) = (r.distance, metric(r)) {
                series.entry(r.label()).or_default().push((d, y));
            }
        }
        chart(
            md,
            (out_dir, charts_dir),
            (
                &format!("{stem}_distance_{key}"),
                &format!("{title}: {desc} vs distance, {device}"),
            ),
            ("camera distance (x default framing)", desc),
            true,
            series,
        )?;
    }
    Ok(())
}

/// The PSNR lost against ε = 0 of the same configuration and pose, a series per pose, and the
/// default ε the results support.
fn epsilon_part(
    md: &mut String,
    records: &[&Record],
    (stem, title, device): (&str, &str, &str),
    out_dir: &Path,
    charts_dir: &Path,
) -> Result<()> {
    // (configuration without ε, pose) -> ε -> PSNR.
    let mut groups: BTreeMap<(String, String), BTreeMap<u64, f64>> = BTreeMap::new();
    let mut distance_of: BTreeMap<String, f64> = BTreeMap::new();
    for r in records.iter().filter(|r| is_lod(r)) {
        if let (Some(e), Some(p)) = (param(r, "epsilon"), r.scores.psnr) {
            groups
                .entry((label_without(r, "epsilon"), r.pose.clone()))
                .or_default()
                .insert(e.to_bits(), p);
            if let Some(d) = r.distance {
                distance_of.insert(r.pose.clone(), d);
            }
        }
    }
    groups.retain(|_, by| by.len() >= 3 && by.contains_key(&0f64.to_bits()));
    if groups.is_empty() {
        return Ok(());
    }
    let configs: Vec<&String> = {
        let mut c: Vec<&String> = groups.keys().map(|(c, _)| c).collect();
        c.dedup();
        c
    };
    let _ = writeln!(md, "### {title}: accuracy lost against ε\n");
    let _ = writeln!(
        md,
        "PSNR against the mesh at ε = 0 minus at ε (dB; the PSNR in brackets), per pose. The \
         default ε is the largest that loses under {LOSS_DB} dB at every pose, or keeps the \
         PSNR above {LOSSLESS_DB} dB (visually lossless) where it loses more.\n"
    );
    let mut series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for config in configs {
        let mut eps: Vec<f64> = groups
            .iter()
            .filter(|((c, _), _)| c == config)
            .flat_map(|(_, by)| by.keys().map(|&b| f64::from_bits(b)))
            .collect();
        eps.sort_by(f64::total_cmp);
        eps.dedup();
        let _ = writeln!(md, "`{config}`:\n");
        let _ = write!(md, "| pose |");
        for e in &eps {
            let _ = write!(md, " ε {e} |");
        }
        let _ = writeln!(md, "\n|---|{}", "---|".repeat(eps.len()));
        // Per ε: whether every pose keeps the loss under LOSS_DB, and under the lossless rule.
        let mut strict = vec![true; eps.len()];
        let mut lossless = vec![true; eps.len()];
        for ((_, pose), by) in groups.iter().filter(|((c, _), _)| c == config) {
            let base = by[&0f64.to_bits()];
            let _ = write!(md, "| {pose} |");
            for (i, e) in eps.iter().enumerate() {
                match by.get(&e.to_bits()) {
                    Some(&p) => {
                        let loss = base - p;
                        let _ = write!(md, " {loss:.2} ({p:.2}) |");
                        strict[i] &= loss < LOSS_DB;
                        lossless[i] &= loss < LOSS_DB || p >= LOSSLESS_DB;
                    }
                    None => {
                        let _ = write!(md, " – |");
                        strict[i] = false;
                        lossless[i] = false;
                    }
                }
                if by.contains_key(&e.to_bits()) {
                    let name = match distance_of.get(pose) {
                        Some(d) => format!("{pose} (distance {d})"),
                        None => pose.clone(),
                    };
                    series
                        .entry(if groups.keys().any(|(c, _)| c != config) {
                            format!("{config} {name}")
                        } else {
                            name
                        })
                        .or_default()
                        .push((*e, base - by[&e.to_bits()]));
                }
            }
            let _ = writeln!(md);
        }
        let largest = |ok: &[bool]| {
            // The largest ε with every smaller ε passing too.
            let n = ok.iter().take_while(|&&b| b).count();
            n.checked_sub(1).map(|i| eps[i])
        };
        let _ = writeln!(
            md,
            "\nLargest ε losing under {LOSS_DB} dB at every pose: {}; with the lossless rule: \
             {}.\n",
            largest(&strict).map_or("none".into(), |e| e.to_string()),
            largest(&lossless).map_or("none".into(), |e| e.to_string())
        );
    }
    chart(
        md,
        (out_dir, charts_dir),
        (
            &format!("{stem}_epsilon_loss"),
            &format!("{title}: PSNR lost vs ε, {device}"),
        ),
        ("ε (pixels)", "PSNR lost against ε = 0 (dB)"),
        false,
        series,
    )
}

/// Frame time and PSNR against the numeric parameter `name` (positive values), a series per
/// configuration and pose; a table with every value, 0 included.
fn param_part(
    md: &mut String,
    records: &[&Record],
    (name, what): (&str, &str),
    (stem, title, device): (&str, &str, &str),
    out_dir: &Path,
    charts_dir: &Path,
) -> Result<()> {
    let swept: Vec<&&Record> = records
        .iter()
        .filter(|r| param(r, name).is_some())
        .collect();
    let mut values: Vec<f64> = swept.iter().filter_map(|r| param(r, name)).collect();
    values.sort_by(f64::total_cmp);
    values.dedup();
    if values.len() < 3 {
        return Ok(());
    }
    let _ = writeln!(md, "### {title}: against the {what}\n");
    let _ = writeln!(
        md,
        "Cells: samples projected / frame ms / PSNR dB ({name} 0: none).\n"
    );
    let _ = write!(md, "| configuration | pose |");
    for v in &values {
        let _ = write!(md, " {v} |");
    }
    let _ = writeln!(md, "\n|---|---|{}", "---|".repeat(values.len()));
    let mut rows: BTreeMap<(String, String), BTreeMap<u64, &Record>> = BTreeMap::new();
    for r in &swept {
        if let Some(v) = param(r, name) {
            rows.entry((label_without(r, name), r.pose.clone()))
                .or_default()
                .insert(v.to_bits(), r);
        }
    }
    for ((config, pose), by) in &rows {
        let _ = write!(md, "| {config} | {pose} |");
        for v in &values {
            let text = by.get(&v.to_bits()).map_or("–".to_string(), |r| cell(r));
            let _ = write!(md, " {text} |");
        }
        let _ = writeln!(md);
    }
    let _ = writeln!(md);
    let metrics: [Metric; 2] = [
        ("ms", "frame time (ms)", |r| Some(r.frame_ms_median)),
        ("psnr", "PSNR (dB)", |r| r.scores.psnr),
    ];
    for (key, desc, metric) in metrics {
        let mut series: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
        for ((config, pose), by) in &rows {
            for (&v, r) in by {
                let v = f64::from_bits(v);
                if let (true, Some(y)) = (v > 0.0, metric(r)) {
                    series
                        .entry(format!("{config} {pose}"))
                        .or_default()
                        .push((v, y));
                }
            }
        }
        chart(
            md,
            (out_dir, charts_dir),
            (
                &format!("{stem}_{name}_{key}"),
                &format!("{title}: {desc} vs {what}, {device}"),
            ),
            (what, desc),
            true,
            series,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::metrics::Scores;

    fn record(method: &str, params: &[(&str, &str)], pose: &str, ms: f64, psnr: f64) -> Record {
        Record {
            model: "m".into(),
            points: 1000,
            method: method.into(),
            params: params
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            width: 64,
            height: 64,
            pose: pose.into(),
            distance: Some(if pose == "near" { 0.5 } else { 4.0 }),
            lights: 1,
            stress: None,
            stress_value: None,
            device: "d".into(),
            driver: "v".into(),
            passes: Vec::new(),
            frame_ms_median: ms,
            frame_ms_iqr: 0.0,
            frame_samples_ms: Vec::new(),
            path_times: Vec::new(),
            invocations: Vec::new(),
            points_per_second: 0.0,
            projected_points: Some(1000),
            projected_per_level: Vec::new(),
            scores: Scores {
                psnr: Some(psnr),
                ..Default::default()
            },
        }
    }

    #[test]
    fn the_section_tabulates_the_loss_and_picks_the_default_epsilon() {
        // Near: 30 dB at ε 0, losing 0.1 / 0.4 / 2 dB; far: 45 dB losing 0.2 / 1.5 / 3.
        let mut records = Vec::new();
        for (pose, base, losses) in [
            ("near", 30.0, [0.1, 0.4, 2.0]),
            ("far", 45.0, [0.2, 1.5, 6.0]),
        ] {
            records.push(record("lod-compute", &[("epsilon", "0")], pose, 10.0, base));
            for (e, loss) in ["0.01", "0.02", "0.05"].iter().zip(losses) {
                records.push(record(
                    "lod-compute",
                    &[("epsilon", e)],
                    pose,
                    5.0,
                    base - loss,
                ));
            }
            records.push(record("points", &[], pose, 20.0, base - 3.0));
        }
        let results = Results {
            device: "d".into(),
            driver: "v".into(),
            created: String::new(),
            records,
            skipped: Vec::new(),
        };
        let dir = std::env::temp_dir().join(format!("surfel-lod-section-{}", std::process::id()));
        let charts = dir.join("charts");
        let md = section(&results, &dir, &charts).expect("section");
        // Strict: 0.02 loses 1.5 dB far; lossless: far stays at 43.5 dB, 0.05 drops to 39.
        assert!(
            md.contains("every pose: 0.01; with the lossless rule: 0.02."),
            "{md}"
        );
        assert!(
            md.contains("| near | 0.00 (30.00) | 0.10 (29.90) | 0.40 (29.60) | 2.00 (28.00) |"),
            "{md}"
        );
        // Distance table and charts: samples, time and PSNR, and the loss chart.
        assert!(
            md.contains("| points | 1000 / 20.0 / 27.00 | 1000 / 20.0 / 42.00 |"),
            "{md}"
        );
        for chart in [
            "distance_samples",
            "distance_ms",
            "distance_psnr",
            "epsilon_loss",
        ] {
            let png = charts.join(format!("lod_m_1000_64x64_{chart}.png"));
            assert!(png.is_file(), "{}", png.display());
        }
        std::fs::remove_dir_all(&dir).expect("cleanup");
        // Without level-of-detail records: nothing.
        let plain = Results {
            records: results
                .records
                .iter()
                .filter(|r| r.method == "points")
                .cloned()
                .collect(),
            ..results
        };
        assert!(section(&plain, &dir, &charts).expect("section").is_empty());
    }
}

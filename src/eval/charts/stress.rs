//! The stress charts: per model and stress kind, hole ratio and PSNR against the stress value.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Result;

use super::axes::{mean, AxisFloor};
use super::line::{LineChart, Series};
use super::select::by_label;
use super::style::Colors;
use super::{slug, write_both};
use crate::eval::config::StressKind;
use crate::eval::metrics::BREAK_HOLE_RATIO;
use crate::eval::results::{stability, Record, Results};

/// Writes the stress charts of `results` into `dir` and returns their paths, each tagged by
/// its model.
pub(super) fn write_stress_charts(
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
            .parse::<StressKind>()
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
    use super::*;
    use crate::eval::charts::tests::record;
    use crate::eval::charts::write_charts;

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

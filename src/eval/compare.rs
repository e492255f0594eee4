//! `surfel bench compare A B`: two timing results (`render --timings` files or `bench`
//! results.json) side by side. For every configuration in both (or the one of each, when both
//! hold one) and every pass, the ratio of B's median to A's with its bootstrap 95 % interval;
//! an interval that excludes 1 is a difference beyond noise. Configurations timed along a
//! camera path in both files are compared frame by frame (`stats::paired_ratio_ci`): frame i
//! shows the same view in both, and the view moves the time more than noise does.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Context as _, Result};

use super::results::Results;
use super::stats::{paired_ratio_ci, ratio_ci, Estimate};
use super::timing::Study;

/// One configuration's raw samples: per pass, then `frame`.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    pub key: String,
    pub passes: Vec<(String, Vec<f64>)>,
    /// The path time of each sample, for configurations timed along a camera path (empty
    /// otherwise).
    pub path_times: Vec<f64>,
}

/// The configurations of a timing results file.
pub fn load(path: &Path) -> Result<Vec<Measured>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    if value.get("records").is_some() {
        let results: Results = serde_json::from_value(value)
            .with_context(|| format!("{}: not a bench results file", path.display()))?;
        return Ok(results
            .records
            .iter()
            .map(|r| {
                let mut passes: Vec<(String, Vec<f64>)> = r
                    .passes
                    .iter()
                    .map(|p| (p.name.clone(), p.samples_ms.clone()))
                    .collect();
                passes.push(("frame".into(), r.frame_samples_ms.clone()));
                let stress = match (&r.stress, r.stress_value) {
                    (Some(kind), Some(v)) => format!(" {kind}={v}"),
                    _ => String::new(),
                };
                Measured {
                    key: format!(
                        "{} {} {} points {}x{} {} lights {}{stress}",
                        r.model,
                        r.label(),
                        r.points,
                        r.width,
                        r.height,
                        r.pose,
                        r.lights
                    ),
                    passes,
                    path_times: r.path_times.clone(),
                }
            })
            .collect());
    }
    let path_times = value
        .get("path_times")
        .and_then(|t| serde_json::from_value::<Vec<f64>>(t.clone()).ok())
        .unwrap_or_default();
    let study: Study = serde_json::from_value(value).with_context(|| {
        format!(
            "{}: neither a `render --timings` file nor a bench results.json",
            path.display()
        )
    })?;
    let mut passes: Vec<(String, Vec<f64>)> = study
        .passes
        .iter()
        .map(|p| (p.name.clone(), p.samples_ms.clone()))
        .collect();
    passes.push(("frame".into(), study.frame.samples_ms.clone()));
    Ok(vec![Measured {
        key: format!(
            "{} {}x{} {} points",
            study.meta.method, study.meta.width, study.meta.height, study.meta.points
        ),
        passes,
        path_times,
    }])
}

/// One pass of one configuration in both files.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub key: String,
    pub pass: String,
    pub a_ms: f64,
    pub b_ms: f64,
    /// B's median over A's, with its interval; for paired samples the median of the
    /// per-frame ratios.
    pub ratio: Estimate,
    /// Compared frame by frame (both timed along the same camera path).
    pub paired: bool,
}

impl Row {
    /// Whether the interval of the ratio excludes 1.
    pub fn differs(&self) -> bool {
        self.ratio.excludes(1.0)
    }
}

/// The rows of every pass both files timed (with samples) in configurations both hold.
pub fn compare(a: &[Measured], b: &[Measured]) -> Result<Vec<Row>> {
    let pairs: Vec<(&Measured, &Measured)> = if a.len() == 1 && b.len() == 1 {
        vec![(&a[0], &b[0])]
    } else {
        a.iter()
            .filter_map(|x| b.iter().find(|y| y.key == x.key).map(|y| (x, y)))
            .collect()
    };
    if pairs.is_empty() {
        bail!("the two files share no configuration");
    }
    let mut rows = Vec::new();
    for (x, y) in pairs {
        let paired = !x.path_times.is_empty() && x.path_times == y.path_times;
        for (pass, sa) in &x.passes {
            let Some((_, sb)) = y.passes.iter().find(|(p, _)| p == pass) else {
                continue;
            };
            let ratio = if paired {
                paired_ratio_ci(sa, sb)
            } else {
                ratio_ci(sa, sb)
            };
            let Some(ratio) = ratio else {
                continue;
            };
            rows.push(Row {
                key: x.key.clone(),
                pass: pass.clone(),
                a_ms: super::stats::median(sa),
                b_ms: super::stats::median(sb),
                ratio,
                paired,
            });
        }
    }
    if rows.is_empty() {
        bail!("no pass has raw samples in both files (results written before samples were kept)");
    }
    Ok(rows)
}

/// The rows as a text table; `*` marks a difference beyond noise, `paired` a comparison frame
/// by frame.
pub fn table(rows: &[Row]) -> String {
    let mut out = String::from(
        "configuration | pass | A ms | B ms | B/A [95 % CI] | beyond noise | samples\n",
    );
    for r in rows {
        writeln!(
            out,
            "{} | {} | {:.3} | {:.3} | {:.3} [{:.3}, {:.3}] | {} | {}",
            r.key,
            r.pass,
            r.a_ms,
            r.b_ms,
            r.ratio.value,
            r.ratio.low,
            r.ratio.high,
            if r.differs() { "*" } else { "" },
            if r.paired { "paired" } else { "independent" }
        )
        .expect("writing to a String");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measured(key: &str, frame: Vec<f64>) -> Measured {
        Measured {
            key: key.into(),
            passes: vec![("frame".into(), frame)],
            path_times: Vec::new(),
        }
    }

    #[test]
    fn configurations_pair_by_key_and_differences_are_marked() {
        let a = vec![
            measured("x", vec![10.0, 10.5, 9.5, 10.2, 9.8]),
            measured("y", vec![5.0, 5.1, 4.9, 5.0, 5.2]),
        ];
        let b = vec![
            measured("y", vec![10.0, 10.1, 9.9, 10.3, 9.7]),
            measured("z", vec![1.0]),
        ];
        let rows = compare(&a, &b).expect("rows");
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].key, "y");
        assert!(rows[0].differs());
        let same = compare(&a, &a).expect("rows");
        assert!(same.iter().all(|r| !r.differs() && r.ratio.value == 1.0));
        assert!(table(&same).lines().count() == 3);
        assert!(compare(&a, &[measured("q", vec![1.0]), measured("r", vec![1.0])]).is_err());
    }

    #[test]
    fn configurations_along_the_same_path_compare_frame_by_frame() {
        let along = |frame: Vec<f64>| Measured {
            path_times: (0..frame.len()).map(|i| i as f64).collect(),
            ..measured("p", frame)
        };
        let a: Vec<f64> = (0..20).map(|i| 5.0 + f64::from(i) * 2.0).collect();
        let b: Vec<f64> = a.iter().map(|x| x * 1.04).collect();
        let rows = compare(&[along(a.clone())], &[along(b.clone())]).expect("rows");
        assert!(rows[0].paired && rows[0].differs(), "{rows:?}");
        assert!(table(&rows).contains("| * | paired"));
        let rows = compare(&[measured("p", a)], &[measured("p", b)]).expect("rows");
        assert!(!rows[0].paired && !rows[0].differs(), "{rows:?}");
    }
}

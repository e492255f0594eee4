//! End-to-end check of the evaluation outputs on a synthetic sweep: JSON round trip, CSV,
//! charts (PNG + SVG) and the markdown report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use surfel::eval::charts::{write_charts, CHART_SIZE};
use surfel::eval::metrics::Scores;
use surfel::eval::report::write_report;
use surfel::eval::results::{PassTiming, Record, Results, Skipped};

const DEVICE: &str = "Test GPU 9000";

/// `(method, params, ms, psnr, ssim)` of the headline configurations. Pareto-optimal on
/// PSNR: points(size=1), points(size=2), pyramid(levels=4).
const METHODS: [(&str, &str, f64, f64, f64); 5] = [
    ("points", "size=1", 1.0, 25.0, 0.80),
    ("points", "size=2", 1.5, 28.0, 0.85),
    ("points", "size=4", 2.0, 27.0, 0.84),
    ("pyramid", "levels=4", 3.0, 33.0, 0.95),
    ("splat", "", 4.0, 31.0, 0.96),
];

fn params(text: &str) -> BTreeMap<String, String> {
    text.split(',')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

fn record(m: usize, points: u64, (w, h): (u32, u32), stress: Option<(&str, f64, f64)>) -> Record {
    let (method, p, ms, psnr, ssim) = METHODS[m];
    // Time grows with pixels and points; accuracy as listed.
    let scale = (f64::from(w * h) / (128.0 * 128.0)) * (points as f64 / 100_000.0).max(0.5);
    let frame = ms * scale;
    let mut passes = vec![PassTiming {
        name: "project".into(),
        median_ms: frame * 0.5,
        iqr_ms: 0.01,
        samples_ms: Vec::new(),
    }];
    if method != "points" {
        passes.push(PassTiming {
            name: "resolve".into(),
            median_ms: frame * 0.3,
            iqr_ms: 0.02,
            samples_ms: Vec::new(),
        });
    }
    passes.push(PassTiming {
        name: "shade".into(),
        median_ms: frame * if method == "points" { 0.5 } else { 0.2 },
        iqr_ms: 0.01,
        samples_ms: Vec::new(),
    });
    Record {
        model: "bunny".into(),
        points,
        method: method.into(),
        params: params(p),
        width: w,
        height: h,
        pose: "default".into(),
        distance: Some(1.0),
        lights: 1,
        stress: stress.map(|s| s.0.to_string()),
        stress_value: stress.map(|s| s.1),
        device: DEVICE.into(),
        driver: "drv 1.2.3".into(),
        passes,
        frame_ms_median: frame,
        frame_ms_iqr: frame * 0.05,
        frame_samples_ms: Vec::new(),
        path_times: Vec::new(),
        invocations: Vec::new(),
        points_per_second: points as f64 / (frame / 1000.0),
        projected_points: None,
        projected_per_level: Vec::new(),
        scores: Scores {
            psnr: Some(psnr - stress.map_or(0.0, |s| s.2 * 100.0)),
            ssim: Some(ssim),
            normal_psnr: None,
            hole_ratio: Some(stress.map_or(0.001, |s| s.2)),
            iou: Some(0.97),
            boundary_px: Some(0.6),
            depth_rel_mean: Some(0.004),
            depth_rel_rms: Some(0.006),
            flicker: Some(1.1),
        },
    }
}

fn synthetic() -> Results {
    let mut records = Vec::new();
    for m in 0..METHODS.len() {
        for res in [(64, 64), (128, 128)] {
            records.push(record(m, 100_000, res, None));
        }
        for points in [10_000, 1_000_000] {
            records.push(record(m, points, (64, 64), None));
        }
        // Subsampling: points(size=1) breaks at 0.25, the others hold.
        for (v, hole) in [(1.0, 0.0), (0.5, 0.004), (0.25, 0.02), (0.1, 0.08)] {
            let hole = if m == 0 { hole } else { hole / 10.0 };
            records.push(record(m, 100_000, (64, 64), Some(("subsample", v, hole))));
        }
        for (v, hole) in [(0.0, 0.0), (45.0, 0.003), (85.0, 0.012)] {
            let hole = if m == 3 { hole / 10.0 } else { hole };
            records.push(record(m, 100_000, (64, 64), Some(("grazing", v, hole))));
        }
    }
    // The ground truth scored against itself: named in the report, never ranked or plotted.
    let mut truth = record(0, 100_000, (128, 128), None);
    truth.method = "mesh".into();
    truth.params.clear();
    truth.frame_ms_median = 40.0;
    truth.scores.psnr = Some(100.0);
    truth.scores.ssim = Some(1.0);
    records.push(truth);
    // A model with a single record: its charts are skipped, not failed.
    let mut lone = record(0, 500, (32, 32), None);
    lone.model = "lone".into();
    records.push(lone);
    Results {
        device: DEVICE.into(),
        driver: "drv 1.2.3".into(),
        created: "2026-01-02T03:04:05Z".into(),
        records,
        skipped: vec![Skipped {
            model: "bunny".into(),
            method: "mesh".into(),
            width: 128,
            height: 128,
            variant: "points=5000".into(),
            reason: "method 'mesh' needs triangle faces; this resampled or stressed cloud has none"
                .into(),
        }],
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn label(m: usize) -> String {
    let (method, p, ..) = METHODS[m];
    if p.is_empty() {
        method.to_string()
    } else {
        format!("{method}({p})")
    }
}

#[test]
fn json_round_trip_and_csv() {
    let dir = scratch("json");
    let results = synthetic();
    let json = dir.join("results.json");
    results.write_json(&json).unwrap();
    let back = Results::read_json(&json).unwrap();
    for (a, b) in back.records.iter().zip(&results.records) {
        assert_eq!(a, b);
    }
    assert_eq!(back, results);

    let csv_path = dir.join("results.csv");
    results.write_csv(&csv_path).unwrap();
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), results.records.len() + 1);
    let header: Vec<&str> = lines[0].split(',').collect();
    for col in [
        "param.levels",
        "param.size",
        "pass.project.median_ms",
        "pass.shade.iqr_ms",
        "pass.resolve.median_ms",
        "psnr",
        "hole_ratio",
    ] {
        assert!(header.contains(&col), "missing column {col}");
    }
    assert!(lines
        .iter()
        .skip(1)
        .all(|l| l.split(',').count() == header.len()));
    std::fs::remove_dir_all(&dir).unwrap();
}

fn assert_chart(path: &Path) {
    let size = std::fs::metadata(path).unwrap().len();
    assert!(size > 2_000, "{} is only {size} bytes", path.display());
    if path.extension().unwrap() == "png" {
        let img = image::open(path).unwrap();
        assert_eq!((img.width(), img.height()), CHART_SIZE);
    } else {
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.contains("<svg"));
        assert!(
            text.contains(DEVICE),
            "{} lacks the device name",
            path.display()
        );
    }
}

#[test]
fn charts_are_written_as_png_and_svg() {
    let dir = scratch("charts");
    let written = write_charts(&synthetic(), &dir).unwrap();
    // The headline slice (128x128, 100,000 points) is named after the model, the other
    // (resolution, points) slices after themselves.
    let mut stems: Vec<String> = [
        "bunny_speed_psnr",
        "bunny_speed_ssim",
        "bunny_passes",
        "bunny_time_vs_resolution",
        "time_vs_points_64x64",
        "bunny_stress_subsample_holes",
        "bunny_stress_subsample_psnr",
        "bunny_stress_grazing_holes",
        "bunny_stress_grazing_psnr",
    ]
    .map(String::from)
    .to_vec();
    for slice in ["1000000pts_64x64", "100000pts_64x64", "10000pts_64x64"] {
        for chart in ["speed_psnr", "speed_ssim", "passes"] {
            stems.push(format!("bunny_{slice}_{chart}"));
        }
    }
    for stem in &stems {
        for ext in ["png", "svg"] {
            let path = dir.join(format!("{stem}.{ext}"));
            assert!(written.contains(&path), "{} not written", path.display());
            assert_chart(&path);
        }
    }
    assert_eq!(written.len(), 2 * stems.len(), "{written:?}");
    assert!(!written
        .iter()
        .any(|p| p.file_name().unwrap().to_string_lossy().starts_with("lone")));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn report_lists_methods_pareto_set_and_stability() {
    let dir = scratch("report");
    let results = synthetic();
    let json = dir.join("results.json");
    results.write_json(&json).unwrap();
    results.write_csv(&dir.join("results.csv")).unwrap();
    let out = dir.join("report");
    let path = write_report(&results, &json, &out).unwrap();
    assert_eq!(path, out.join("report.md"));
    let md = std::fs::read_to_string(&path).unwrap();
    assert!(md.contains(DEVICE) && md.contains("drv 1.2.3") && md.contains("2026-01-02"));
    assert!(md.contains("[../results.json](../results.json)"));
    assert!(md.contains("; jobs skipped: 1"));
    let skipped = md.split("## Skipped jobs").nth(1).expect("skipped section");
    assert!(skipped.contains(
        "| bunny | mesh | 128x128 | points=5000 | method 'mesh' needs triangle faces; this \
         resampled or stressed cloud has none |"
    ));
    // The compact table: what all rows share above it, one row per configuration.
    let table = md.split("## Model `bunny`").nth(1).expect("bunny section");
    assert!(table
        .trim_start()
        .starts_with("All rows: pose default, lights 1.\n"));
    assert!(table.contains("| configuration | frame ms [95 % CI] | PSNR dB | SSIM | hole % |"));
    for m in 0..METHODS.len() {
        assert!(
            table.contains(&format!(
                "| {}, resolution 64x64, points 100000 |",
                label(m)
            )),
            "{}",
            label(m)
        );
    }
    assert!(table.contains(
        "| points(size=1), resolution 64x64, points 100000 | 0.250 | 25.00 | 0.8000 | 0.10 |"
    ));
    // The wide table is the CSV's, linked from the header.
    assert!(md.contains("[../results.csv](../results.csv)"));

    let section = md
        .split("### Pareto set: GPU time vs PSNR dB (128x128, 100000 points)")
        .nth(1)
        .expect("PSNR Pareto section")
        .trim_start()
        .split("\n\n")
        .next()
        .unwrap();
    let pareto: Vec<&str> = section
        .lines()
        .skip(2)
        .map(|l| l.split('|').nth(1).unwrap().trim())
        .collect();
    assert_eq!(pareto, [label(0), label(1), label(3)]);
    assert!(md.contains("Reference (not ranked): `mesh`, 40.000 ms."));

    let stability = md.split("## Stability under stress").nth(1).unwrap();
    assert!(stability.contains(&format!("| {} | breaks at 85 | breaks at 0.25 |", label(0))));
    assert!(stability.contains(&format!("| {} | stable | stable |", label(3))));
    assert!(stability.contains(&format!("| {} | breaks at 85 | stable |", label(4))));

    for link in [
        "charts/bunny_speed_psnr.png",
        "charts/bunny_passes.png",
        "charts/time_vs_points_64x64.png",
    ] {
        assert!(md.contains(&format!("]({link})")), "no link to {link}");
        assert!(out.join(link).exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

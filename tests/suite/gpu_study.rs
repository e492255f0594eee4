//! `benches/gpu-study.sh` in its dry run on lavapipe (small clouds, 128x128, validation layers
//! on): the script the GPU machine runs must finish and write every measurement it promises.

use std::path::Path;
use std::process::Command;

use surfel::eval::results::Results;

/// Cloud sizes of the render timings, and of the bench's sampled dragon.
const COUNTS: [u64; 2] = [20_000, 50_000];
const BENCH_POINTS: u64 = 20_000;
/// The script's default bench methods: one per family, `mesh` the ground truth.
const FAMILIES: [&str; 12] = [
    "points",
    "compute",
    "compute-hq",
    "perspective-deferred",
    "affine-flat",
    "ewa",
    "pyramid",
    "kernel5",
    "hpr",
    "lod-compute",
    "lod-mesh",
    "mesh",
];

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn dry_run_writes_timings_anchor_note_and_bench_report() {
    let out = std::env::temp_dir().join(format!("surfel-gpu-study-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut cmd = Command::new("bash");
    cmd.arg("benches/gpu-study.sh")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    for (key, _) in std::env::vars().filter(|(k, _)| k.starts_with("GPU_STUDY_")) {
        cmd.env_remove(key);
    }
    let counts = COUNTS.map(|n| n.to_string()).join(" ");
    let run = cmd
        .env("GPU_STUDY_DRY", "1")
        .env("GPU_STUDY_POINTS", &counts)
        .env("GPU_STUDY_BENCH_POINTS", BENCH_POINTS.to_string())
        .env("SURFEL_BIN", env!("CARGO_BIN_EXE_surfel"))
        .env("OUT", &out)
        .output()
        .expect("bash");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.success(),
        "gpu-study.sh failed ({}):\n{stdout}\n{stderr}",
        run.status
    );

    // Every step ran and succeeded, surfel's GPU commands with the validation layers.
    let steps = read(&out.join("steps.tsv"));
    for line in steps.lines().skip(1) {
        assert_eq!(line.split('\t').nth(1), Some("0"), "step failed: {line}");
    }
    assert_eq!(steps.lines().count(), 1 + 2 * 3 + 1, "{steps}");
    let log = read(&out.join("surfel.txt"));
    let gpu_commands: Vec<&str> = log
        .lines()
        .filter(|l| l.starts_with("== render") || l.starts_with("== bench"))
        .collect();
    assert_eq!(gpu_commands.len(), 5, "{log}");
    assert!(
        gpu_commands.iter().all(|l| l.ends_with("--validation")),
        "{gpu_commands:#?}"
    );
    assert!(read(&out.join("device.txt")).contains("device "));
    assert!(read(&out.join("anchor.txt")).contains("dry run"));

    // (a) per-pass and frame timings of `compute` and `points` at both sizes.
    let study = read(&out.join("study.md"));
    for n in COUNTS {
        for method in ["compute", "points"] {
            let file = out.join(format!("timings/{method}-{n}.json"));
            let t: serde_json::Value = serde_json::from_str(&read(&file)).expect("timings JSON");
            assert_eq!(t["meta"]["points"], n, "{}", file.display());
            assert_eq!(
                (t["meta"]["width"].as_u64(), t["meta"]["height"].as_u64()),
                (Some(128), Some(128))
            );
            let frame = t["frame"]["median_ms"].as_f64().expect("frame median");
            assert!(
                frame.is_finite() && frame > 0.0,
                "{}: {frame}",
                file.display()
            );
            let passes = t["passes"].as_array().expect("passes");
            assert!(!passes.is_empty(), "{}", file.display());
            assert!(out.join(format!("images/{method}-{n}.png")).is_file());
            for extra in ["csv", "trace.json"] {
                let path = out.join(format!("timings/{method}-{n}.{extra}"));
                assert!(path.is_file(), "{}", path.display());
            }
            assert!(study.contains(&format!("| {method} | {n} | ")), "{study}");
        }
    }

    // (b) every family on the sampled dragon, scored against the mesh, with pass timings.
    let bench = out.join("bench");
    let results = Results::read_json(&bench.join("results.json")).expect("results.json");
    for family in FAMILIES {
        let records: Vec<_> = results
            .records
            .iter()
            .filter(|r| r.method == family)
            .collect();
        assert!(!records.is_empty(), "no record of {family}");
        for r in &records {
            assert!(
                r.frame_ms_median > 0.0 && !r.passes.is_empty(),
                "{family}: {} ms, {:?}",
                r.frame_ms_median,
                r.passes
            );
        }
        if family == "mesh" {
            continue;
        }
        let sampled = records
            .iter()
            .find(|r| r.points == BENCH_POINTS)
            .unwrap_or_else(|| panic!("no record of {family} on {BENCH_POINTS} points"));
        let psnr = sampled.scores.psnr.expect("PSNR");
        assert!(psnr.is_finite() && psnr > 0.0, "{family}: PSNR {psnr}");
    }
    let report = read(&bench.join("report.md"));
    assert!(report.contains("## Model `dragon`"));
    // Every family also timed along the camera path, one sample per path frame.
    assert!(report.contains("### Along camera paths"), "{report}");
    let flights: Vec<_> = results
        .records
        .iter()
        .filter(|r| r.pose == "flight")
        .collect();
    assert!(!flights.is_empty());
    for r in flights {
        assert_eq!(
            (r.path_times.len(), r.frame_samples_ms.len()),
            (4, 4),
            "{}",
            r.label()
        );
    }
    assert!(bench.join("sweep.toml").is_file() && bench.join("results.csv").is_file());
    let charts = std::fs::read_dir(bench.join("charts"))
        .expect("charts")
        .count();
    assert!(charts > 0);

    std::fs::remove_dir_all(&out).ok();
}

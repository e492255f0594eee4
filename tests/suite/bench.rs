//! `surfel bench --quick` on lavapipe: results, charts and report for `points` and the `mesh`
//! ground truth, with validation on.

use crate::common;

use surfel::eval::bench;
use surfel::eval::config::{quick_sweep_dir, BenchConfig, SweepOrigin};
use surfel::eval::results::Results;

#[test]
fn quick_sweep_writes_results_charts_and_report() {
    let ctx = common::context();
    let out = std::env::temp_dir().join(format!("surfel-bench-{}", std::process::id()));
    let config = BenchConfig::quick().expect("quick sweep");
    let run = bench::run(&ctx, &config, &out, false).expect("sweep");
    common::assert_clean(&ctx);

    let results = Results::read_json(&run.json).expect("results.json");
    assert_eq!(results, run.results);
    assert_eq!(results.device, ctx.caps.device_name);
    let csv = std::fs::read_to_string(&run.csv).expect("csv");
    assert_eq!(csv.lines().count(), results.records.len() + 1);

    let find = |method: &str, size: Option<&str>, points: u64, stress: Option<(&str, f64)>| {
        results
            .records
            .iter()
            .find(|r| {
                r.method == method
                    && r.params.get("size").map(String::as_str) == size
                    && r.points == points
                    && r.width == 64
                    && r.stress.as_deref() == stress.map(|s| s.0)
                    && r.stress_value == stress.map(|s| s.1)
            })
            .unwrap_or_else(|| panic!("no record {method} {size:?} {points} {stress:?}"))
    };
    // The ground truth scored against itself is perfect.
    let mesh = find("mesh", None, 35_947, None);
    assert_eq!(mesh.scores.psnr, Some(100.0));
    assert_eq!(mesh.scores.iou, Some(1.0));
    assert!(mesh
        .passes
        .iter()
        .any(|p| p.name == "mesh.raster" && p.median_ms > 0.0));
    // 1 px points of a 2 000-point resample leave holes; the full bunny at 64x64 does not.
    let sparse = find("points", Some("1"), 2000, None);
    let full = find("points", Some("1"), 35_947, None);
    assert!(
        sparse.scores.hole_ratio.expect("holes") > 0.05,
        "{:?}",
        sparse.scores
    );
    assert!(
        full.scores.hole_ratio.expect("holes") < 0.01,
        "{:?}",
        full.scores
    );
    assert!(full.scores.psnr.expect("psnr") > sparse.scores.psnr.expect("psnr"));
    assert!(
        full.scores.flicker.is_some(),
        "baseline jobs measure flicker"
    );
    // Magnifying until points are 8 px apart breaks 1 px points.
    let magnified = find("points", Some("1"), 35_947, Some(("magnification", 8.0)));
    assert!(
        magnified.scores.hole_ratio.expect("holes") > 0.2,
        "{:?}",
        magnified.scores
    );
    for r in &results.records {
        assert!(
            r.frame_ms_median > 0.0 && r.points_per_second > 0.0,
            "{r:?}"
        );
        // Methods without level of detail project every point.
        assert_eq!(r.projected_points, Some(r.points), "{r:?}");
        assert!(r.projected_per_level.is_empty(), "{r:?}");
        for (name, v) in r.scores.fields() {
            assert!(v.is_none_or(f64::is_finite), "{name} = {v:?} in {r:?}");
        }
    }

    let charts: Vec<String> = run
        .charts
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    for expected in [
        "bunny_speed_psnr.png",
        "bunny_speed_ssim.svg",
        "bunny_passes.png",
        "time_vs_points_128x128.png",
        "time_vs_points_64x64.png",
        "bunny_time_vs_resolution.png",
        "bunny_stress_magnification_holes.png",
    ] {
        assert!(
            charts.iter().any(|c| c == expected),
            "missing {expected} in {charts:?}"
        );
    }
    let report = surfel::eval::report::write_report(&results, &run.json, &out).expect("report");
    let text = std::fs::read_to_string(report).expect("report.md");
    assert!(text.contains("llvmpipe") || text.contains(&results.device));
    assert!(text.contains("Pareto") && text.contains("points(size=1)"));
    assert!(text.contains("Reference (not ranked): `mesh`"), "{text}");
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn lod_jobs_record_the_samples_read_back_per_level() {
    let ctx = common::context();
    let out = std::env::temp_dir().join(format!("surfel-bench-lod-{}", std::process::id()));
    let sweep = r#"
        resolutions = ["64x64"]
        lights = [1]
        [frames]
        warmup = 0
        measured = 1
        [[models]]
        name = "bunny"
        path = "../../../shared/data/stanford/bun_zipper.ply"
        [[methods]]
        name = "lod-compute"
        [[methods]]
        name = "points"
        [[poses]]
        name = "default"
    "#;
    // Model paths relative to the quick sweep's directory.
    let origin = SweepOrigin::File(quick_sweep_dir().join("lod-samples.toml"));
    let config = BenchConfig::parse_from(sweep, origin).expect("sweep");
    let run = bench::run(&ctx, &config, &out, false).expect("sweep");
    common::assert_clean(&ctx);
    let record = |method: &str| {
        let found = run.results.records.iter().find(|r| r.method == method);
        found.unwrap_or_else(|| panic!("no {method} record"))
    };
    let lod = record("lod-compute");
    // Every level of the object texture counted; the framed bunny draws coarse levels, so
    // fewer samples than points.
    assert_eq!(lod.projected_per_level.len(), 4, "{lod:?}");
    let total: u64 = lod.projected_per_level.iter().sum();
    assert_eq!(lod.projected_points, Some(total));
    assert!(total > 0 && total < lod.points, "{lod:?}");
    let points = record("points");
    assert_eq!(points.projected_points, Some(points.points));
    assert!(points.projected_per_level.is_empty());
    let csv = std::fs::read_to_string(&run.csv).expect("csv");
    let header = csv.lines().next().expect("header");
    for column in [
        "projected_points",
        "projected_points_l0",
        "projected_points_l3",
    ] {
        assert!(header.split(',').any(|c| c == column), "{header}");
    }
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn a_path_pose_is_timed_at_every_frame_and_scored_at_its_first_key() {
    let ctx = common::context();
    let out = std::env::temp_dir().join(format!("surfel-bench-path-{}", std::process::id()));
    let sweep = r#"
        resolutions = ["64x64"]
        lights = [1]
        [frames]
        warmup = 1
        measured = 4
        [[models]]
        name = "bunny"
        path = "../../../shared/data/stanford/bun_zipper.ply"
        [[methods]]
        name = "points"
        [[methods]]
        name = "compute"
        [[poses]]
        name = "start"
        orbit = [0.0, 15.0]
        [[poses]]
        name = "flight"
        path = "../paths/orbit-zoom.toml"
    "#;
    let origin = SweepOrigin::File(quick_sweep_dir().join("path-test.toml"));
    let config = BenchConfig::parse_from(sweep, origin).expect("sweep");
    let run = bench::run(&ctx, &config, &out, false).expect("sweep");
    common::assert_clean(&ctx);
    let path =
        surfel::scene::path::CameraPath::load(&quick_sweep_dir().join("../paths/orbit-zoom.toml"))
            .expect("path");
    for method in ["points", "compute"] {
        let record = |pose: &str| {
            run.results
                .records
                .iter()
                .find(|r| r.method == method && r.pose == pose)
                .unwrap_or_else(|| panic!("no {method} record at {pose}"))
        };
        let (start, flight) = (record("start"), record("flight"));
        // One timed frame per path frame, each with its path time.
        assert_eq!(flight.path_times, path.times(), "{method}");
        assert_eq!(flight.frame_samples_ms.len(), path.frames as usize);
        assert!(flight.frame_samples_ms.iter().all(|&ms| ms > 0.0));
        assert_eq!(start.frame_samples_ms.len(), 4);
        assert!(start.path_times.is_empty());
        // The scored frame is the first key's pose: the fixed pose "start".
        assert_eq!(flight.scores, start.scores, "{method}");
    }
    let charts: Vec<String> = run
        .charts
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    assert!(
        charts.iter().any(|c| c == "bunny_path_flight.png"),
        "{charts:?}"
    );
    let report = surfel::eval::report::write_report(&run.results, &run.json, &out).expect("report");
    let text = std::fs::read_to_string(report).expect("report.md");
    let paths = text
        .split("### Along camera paths")
        .nth(1)
        .expect("path table");
    assert!(
        paths.contains("| flight | points, 64x64, points 35947, lights 1 | 60 |"),
        "{paths}"
    );
    assert!(text.contains("charts/bunny_path_flight.png"));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn a_sweep_with_pipeline_stats_counts_each_passes_invocations() {
    let ctx = common::context();
    let out = std::env::temp_dir().join(format!("surfel-bench-stats-{}", std::process::id()));
    let sweep = r#"
        resolutions = ["64x64"]
        lights = [1]
        [frames]
        warmup = 0
        measured = 2
        pipeline_stats = true
        [[models]]
        name = "bunny"
        path = "../../../shared/data/stanford/bun_zipper.ply"
        [[methods]]
        name = "points"
    "#;
    let origin = SweepOrigin::File(quick_sweep_dir().join("stats-test.toml"));
    let config = BenchConfig::parse_from(sweep, origin).expect("sweep");
    let run = bench::run(&ctx, &config, &out, false).expect("sweep");
    common::assert_clean(&ctx);
    let points = run
        .results
        .records
        .iter()
        .find(|r| r.method == "points")
        .expect("points record");
    // One vertex invocation per point, as `render --pipeline-stats` counts.
    let project = points
        .invocations
        .iter()
        .find(|i| i.name == "points.project")
        .unwrap_or_else(|| panic!("{:?}", points.invocations));
    assert_eq!(project.vertex, points.points as f64);
    assert!(project.fragment > 0.0);
    // The ground truth is rendered without the queries.
    let mesh = run.results.records.iter().find(|r| r.method == "mesh");
    assert!(mesh.is_none_or(|m| m.invocations.is_empty()));
    let csv = std::fs::read_to_string(&run.csv).expect("csv");
    // Fields split at commas outside quotes (the device name has one).
    let fields = |line: &str| {
        let mut out = vec![String::new()];
        let mut quoted = false;
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => out.push(String::new()),
                c => out.last_mut().expect("field").push(c),
            }
        }
        out
    };
    let header = fields(csv.lines().next().expect("header"));
    let row = fields(
        csv.lines()
            .skip(1)
            .find(|l| l.contains(",points,"))
            .expect("points row"),
    );
    let at = header
        .iter()
        .position(|c| *c == "pass.points.project.vertex_invocations")
        .expect("invocation column");
    assert_eq!(row[at], points.points.to_string());
    std::fs::remove_dir_all(&out).ok();
}

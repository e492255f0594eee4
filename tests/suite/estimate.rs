//! The GPU estimate of normals and radii (`estimate`) on lavapipe under synchronization
//! validation, against the CPU's (`scene::preprocess`): the same k-th neighbour distance for
//! every point (so the same radii), and normals within a small angle (single precision and
//! ties between equidistant neighbours may differ), on a scanned mesh, a dense mesh and a
//! LiDAR tile; and a cloud of outliers, duplicates and non-finite points that the GPU leaves
//! partly to the CPU's exact search.

use crate::common;

use std::path::PathBuf;

use glam::Vec3;
use surfel::knn_gpu::{self, GpuKnn};
use surfel::rng::SplitMix64;
use surfel::scene::preprocess::{self, PreprocessOptions};
use surfel::scene::{self, Cloud};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

fn bare(cloud: Cloud) -> Cloud {
    Cloud {
        normals: None,
        radii: None,
        faces: None,
        ..cloud
    }
}

fn options() -> PreprocessOptions {
    PreprocessOptions {
        progress: false,
        ..Default::default()
    }
}

/// Estimates `cloud` on the CPU and on the GPU; returns both and the GPU's unresolved count.
fn both(ctx: &std::sync::Arc<surfel::gpu::Context>, cloud: &Cloud) -> (Cloud, Cloud, usize) {
    let mut cpu = cloud.clone();
    preprocess::preprocess(&mut cpu, &options());
    let mut gpu = cloud.clone();
    let times = knn_gpu::estimate(ctx, &mut gpu, &options())
        .expect("GPU estimate")
        .expect("something to estimate");
    common::assert_clean(ctx);
    (cpu, gpu, times.unresolved)
}

/// The same radii (the k-th distance is exact on both; only its last bits may differ) and
/// normals within `median`, `p99` degrees at the median and the 99th percentile.
fn assert_close(name: &str, cpu: &Cloud, gpu: &Cloud, median: f32, p99: f32) {
    let (rc, rg) = (cpu.radii.as_ref().unwrap(), gpu.radii.as_ref().unwrap());
    for (i, (a, b)) in rc.iter().zip(rg).enumerate() {
        assert!(
            (a - b).abs() <= 1e-5 * a.max(*b),
            "{name}: point {i}: radius {b} on the GPU, {a} on the CPU"
        );
    }
    let (nc, ng) = (cpu.normals.as_ref().unwrap(), gpu.normals.as_ref().unwrap());
    assert!(
        ng.iter().all(|n| (n.length() - 1.0).abs() < 1e-3),
        "{name}: unit normals"
    );
    let d = common::angles(nc, ng);
    let at = |q: f64| d[((d.len() - 1) as f64 * q) as usize];
    eprintln!(
        "{name}: {} points, angle median {:.4}°, 99% {:.3}°, 99.9% {:.2}°, max {:.1}°",
        d.len(),
        at(0.5),
        at(0.99),
        at(0.999),
        d[d.len() - 1]
    );
    assert!(at(0.5) <= median, "{name}: median angle {}°", at(0.5));
    assert!(at(0.99) <= p99, "{name}: 99th percentile {}°", at(0.99));
}

#[test]
fn gpu_estimate_matches_the_cpu_on_scans() {
    let ctx = common::context();
    for rel in [
        "stanford/bun_zipper.ply",
        "stanford/dragon_vrip.ply",
        "lidar/autzen_trim.laz",
    ] {
        let cloud = bare(scene::load(&data(rel)).unwrap_or_else(|e| panic!("{e}")));
        let (cpu, gpu, _) = both(&ctx, &cloud);
        assert_close(rel, &cpu, &gpu, 0.01, 0.1);
    }
}

#[test]
fn gpu_leaves_outliers_and_non_finite_points_to_the_cpu() {
    let ctx = common::context();
    let mut rng = SplitMix64::new(7);
    // A noisy plane of 20,000 points, 200 duplicates, 50 far outliers and 30 non-finite.
    let mut positions: Vec<Vec3> = (0..20_000)
        .map(|_| {
            let (x, y) = (rng.next_f64() as f32 * 10.0, rng.next_f64() as f32 * 10.0);
            Vec3::new(x, y, 0.002 * rng.next_f64() as f32 + 0.05 * (x * 0.7).sin())
        })
        .collect();
    let copies: Vec<Vec3> = positions[..200].to_vec();
    positions.extend(copies);
    positions.extend((0..50).map(|i| Vec3::new(60.0 + 7.0 * i as f32, -40.0, 25.0)));
    positions.extend((0..30).map(|i| match i % 3 {
        0 => Vec3::new(f32::NAN, 1.0, 1.0),
        1 => Vec3::new(1.0, f32::INFINITY, 1.0),
        _ => Vec3::splat(f32::NEG_INFINITY),
    }));
    let cloud = Cloud {
        positions,
        ..Cloud::default()
    };
    let (cpu, gpu, unresolved) = both(&ctx, &cloud);
    // The outliers have no k neighbours within any 5×5×5 block.
    assert!(unresolved >= 50, "{unresolved} unresolved points");
    assert_close("plane with outliers", &cpu, &gpu, 0.01, 0.1);
    let normals = gpu.normals.as_ref().unwrap();
    assert!(
        normals[20_250..20_280].iter().all(|&n| n == Vec3::Z),
        "non-finite points keep +Z"
    );
    // Outliers' neighbourhoods came from the CPU's search: identical.
    let cpu_normals = cpu.normals.as_ref().unwrap();
    assert_eq!(normals[20_200..20_250], cpu_normals[20_200..20_250]);
}

#[test]
fn gpu_estimate_rejects_what_it_cannot_hold() {
    let ctx = common::context();
    let error = GpuKnn::new(&ctx, 33).err().expect("k = 33 refused");
    assert_eq!(
        error.to_string(),
        "the GPU estimate keeps 1 to 32 neighbours per point, not 33"
    );
    // Larger neighbourhoods and small clouds fall back to the CPU, with the CPU's result.
    let mut cloud = bare(common::square(40));
    let mut cpu = cloud.clone();
    let options = PreprocessOptions { k: 40, ..options() };
    preprocess::preprocess(&mut cpu, &options);
    let times = knn_gpu::estimate(&ctx, &mut cloud, &options)
        .expect("estimate")
        .expect("estimated");
    assert_eq!((times.gpu_s, times.unresolved), (0.0, 0));
    assert_eq!(cloud.normals, cpu.normals);
    assert_eq!(cloud.radii, cpu.radii);
}

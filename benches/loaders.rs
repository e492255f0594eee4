//! Loader throughput and preprocessing speed on the shared test data.
//!
//! `SURFEL_DATA` overrides the data folder (default `../shared/data` beside the crate).

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use surfel::scene::{self, las, pcd, ply, preprocess, sample, Cloud};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(data(rel)).expect("test data")
}

fn sampled_dragon(n: usize) -> Cloud {
    let dragon = scene::load(&data("stanford/dragon_vrip.ply")).expect("dragon");
    sample::sample_mesh(&dragon, n, 1).expect("sampling")
}

fn loaders(c: &mut Criterion) {
    let mut group = c.benchmark_group("parse");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));

    let mut binary = Vec::new();
    ply::write_binary(&sampled_dragon(1_000_000), &mut binary).expect("write");
    group.throughput(Throughput::Bytes(binary.len() as u64));
    group.bench_function("ply binary (1M sampled dragon)", |b| {
        b.iter(|| ply::parse("dragon.ply", &binary).expect("parse"))
    });

    let ascii = read("stanford/dragon_vrip.ply");
    group.throughput(Throughput::Bytes(ascii.len() as u64));
    group.bench_function("ply ascii (dragon_vrip)", |b| {
        b.iter(|| ply::parse("dragon_vrip.ply", &ascii).expect("parse"))
    });

    let compressed = read("pcd/table_scene_mug_stereo_textured.pcd");
    group.throughput(Throughput::Bytes(compressed.len() as u64));
    group.bench_function("pcd binary_compressed (table_scene)", |b| {
        b.iter(|| pcd::parse("table.pcd", &compressed).expect("parse"))
    });

    for file in ["lidar/autzen_trim.las", "lidar/autzen_trim.laz"] {
        let bytes = read(file);
        group.throughput(Throughput::Bytes(bytes.len() as u64));
        group.bench_function(file, |b| {
            b.iter(|| las::parse(file, bytes.clone()).expect("parse"))
        });
    }
    group.finish();
}

fn preprocessing(c: &mut Criterion) {
    let mut group = c.benchmark_group("normals+radii");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    let options = preprocess::PreprocessOptions {
        progress: false,
        ..Default::default()
    };
    for n in [100_000, 1_000_000] {
        let mut cloud = sampled_dragon(n);
        cloud.normals = None;
        cloud.radii = None;
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(format!("{n} points, k=10"), |b| {
            b.iter(|| {
                let mut c = cloud.clone();
                preprocess::preprocess(&mut c, &options);
                c
            })
        });
    }
    group.finish();
}

criterion_group!(benches, loaders, preprocessing);
criterion_main!(benches);

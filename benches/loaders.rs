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

/// Autzen's point records repeated `copies` times behind its header (a LAS 1.2 file, so the
/// point count is the 32-bit field at byte 107).
fn repeated_las(copies: u32) -> Vec<u8> {
    let autzen = read("lidar/autzen_trim.las");
    let at = u32::from_le_bytes(autzen[96..100].try_into().expect("offset")) as usize;
    let count = u32::from_le_bytes(autzen[107..111].try_into().expect("count"));
    let mut bytes = autzen[..at].to_vec();
    bytes[107..111].copy_from_slice(&(count * copies).to_le_bytes());
    for _ in 0..copies {
        bytes.extend_from_slice(&autzen[at..]);
    }
    bytes
}

fn loaders(c: &mut Criterion) {
    let threads = rayon::current_num_threads();
    let mut group = c.benchmark_group(format!("parse ({threads} threads)"));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));

    for n in [1_000_000, 10_000_000] {
        let mut binary = Vec::new();
        ply::write_binary(&sampled_dragon(n), &mut binary).expect("write");
        group.throughput(Throughput::Bytes(binary.len() as u64));
        group.bench_function(format!("ply binary ({n} sampled dragon, memory)"), |b| {
            b.iter(|| ply::parse("dragon.ply", &binary).expect("parse"))
        });
        let path = std::env::temp_dir().join(format!("surfel-bench-{n}.ply"));
        std::fs::write(&path, &binary).expect("write");
        drop(binary);
        group.bench_function(format!("ply binary ({n} sampled dragon, file)"), |b| {
            b.iter(|| ply::load(&path).expect("load"))
        });
        std::fs::remove_file(&path).expect("remove");
    }

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
    let big = repeated_las(30);
    group.throughput(Throughput::Bytes(big.len() as u64));
    let path = std::env::temp_dir().join("surfel-bench-autzen30.las");
    std::fs::write(&path, &big).expect("write");
    group.bench_function("las (autzen x30, 3.3M points, file)", |b| {
        b.iter(|| las::load(&path).expect("load"))
    });
    std::fs::remove_file(&path).expect("remove");
    group.finish();

    let mut group = c.benchmark_group(format!("sample ({threads} threads)"));
    group.sample_size(10);
    let dragon = scene::load(&data("stanford/dragon_vrip.ply")).expect("dragon");
    let n = 1_000_000;
    group.throughput(Throughput::Elements(n as u64));
    group.bench_function("sample + write 1M points (dragon_vrip)", |b| {
        b.iter(|| {
            let cloud = sample::sample_mesh(&dragon, n, 1).expect("sampling");
            let mut bytes = Vec::new();
            ply::write_binary(&cloud, &mut bytes).expect("write");
            bytes
        })
    });
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

fn formats(c: &mut Criterion) {
    let threads = rayon::current_num_threads();
    let mut group = c.benchmark_group(format!("formats ({threads} threads)"));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    for file in ["e57/bunnyFloat.e57", "copc/1.2-with-color.copc.laz"] {
        let path = data(file);
        group.throughput(Throughput::Bytes(
            std::fs::metadata(&path).expect("data").len(),
        ));
        group.bench_function(file, |b| b.iter(|| scene::load(&path).expect("load")));
    }
    for n in [1_000_000, 10_000_000] {
        let cloud = sampled_dragon(n);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(format!("duplicates ({n} sampled dragon)"), |b| {
            b.iter(|| cloud.duplicates())
        });
    }
    group.finish();
}

criterion_group!(benches, loaders, preprocessing, formats);
criterion_main!(benches);

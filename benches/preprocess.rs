//! Normals and radii throughput: the grid estimation (`scene::preprocess`) against the k-d tree
//! reference it replaced (one tree query per point, then the Jacobi eigen solve per point), on
//! the dragon sampled to 1 M and 10 M points without normals, with 1 thread and with all
//! threads; then the GPU estimate (`estimate`) on the first Vulkan device (`SURFEL_DEVICE`
//! chooses), whole (pipelines, grid frame, upload, passes, read-back and the CPU's finish) and
//! its submission alone; and the orientation of the normals alone (`scene::orient`, every
//! second normal flipped first) by each rule. Prints Markdown tables of points per second (the
//! median of `RUNS` runs; the tree at 10 M once).
//!
//! `cargo bench --bench preprocess`; `SURFEL_DATA` overrides the data folder.

use std::path::PathBuf;
use std::time::Instant;

use std::sync::Arc;

use surfel::gpu::{Context, ContextOptions};
use surfel::scene::preprocess::{self, Neighbours, PreprocessOptions, RadiusMode};
use surfel::scene::{self, sample, Cloud};

const RUNS: usize = 3;

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

/// Median seconds of `runs` calls of `f`.
fn seconds(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    let dragon = scene::load(&data("stanford/dragon_vrip.ply")).expect("dragon");
    let all = rayon::current_num_threads();
    println!("| points | threads | grid (points/s) | k-d tree reference (points/s) | speed-up |");
    println!("|---:|---:|---:|---:|---:|");
    for n in [1_000_000, 10_000_000] {
        let cloud = Cloud {
            normals: None,
            radii: None,
            ..sample::sample_mesh(&dragon, n, 1).expect("sampling")
        };
        for threads in [1, all] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let options = PreprocessOptions {
                progress: false,
                ..Default::default()
            };
            let grid = pool.install(|| {
                seconds(RUNS, || {
                    let mut c = cloud.clone();
                    preprocess::preprocess(&mut c, &options);
                })
            });
            let tree_runs = if n > 1_000_000 { 1 } else { RUNS };
            let tree = pool.install(|| {
                seconds(tree_runs, || {
                    let p = &cloud.positions;
                    let nb = Neighbours::compute_with_tree(p, preprocess::DEFAULT_K);
                    preprocess::estimate_normals(&cloud, &nb, false);
                    preprocess::estimate_radii(p, &nb, RadiusMode::DensitySpacing);
                })
            });
            println!(
                "| {n} | {threads} | {:.2} M | {:.2} M | {:.1}× |",
                n as f64 / grid / 1e6,
                n as f64 / tree / 1e6,
                tree / grid
            );
        }
    }
    orientation(&dragon);
    gpu(&dragon);
}

/// The orientation table: seconds of `orient` alone per rule, on all threads.
fn orientation(dragon: &Cloud) {
    use surfel::scene::orient::{self, Graph, Rule, GRAPH_K};
    println!("\n| points | rule | orientation (s) | points/s |");
    println!("|---:|---|---:|---:|");
    for n in [1_000_000, 10_000_000] {
        let cloud = Cloud {
            normals: None,
            radii: None,
            ..sample::sample_mesh(dragon, n, 1).expect("sampling")
        };
        let nb = Neighbours::compute(&cloud.positions, preprocess::DEFAULT_K, false);
        let mut graph = Graph::new(n);
        for (i, row) in graph.rows.chunks_mut(GRAPH_K).enumerate() {
            for (slot, &j) in row.iter_mut().zip(nb.of(i).0) {
                *slot = j;
            }
        }
        let mut normals = preprocess::estimate_normals(&cloud, &nb, false);
        for n in normals.iter_mut().step_by(2) {
            *n = -*n;
        }
        for (name, rule) in [
            ("propagation", Rule::Propagate),
            ("up, propagated below 60°", Rule::Up(scene::Up::Y)),
        ] {
            let s = seconds(RUNS, || {
                let mut work = normals.clone();
                orient::orient(&cloud, &mut work, &graph, rule);
            });
            println!("| {n} | {name} | {s:.3} | {:.2} M |", n as f64 / s / 1e6);
        }
    }
}

/// The GPU table: median whole and submission throughput over `RUNS` runs.
fn gpu(dragon: &Cloud) {
    let ctx = match Context::new(&ContextOptions::from_env()) {
        Ok(ctx) => Arc::new(ctx),
        Err(e) => {
            println!("\nno GPU estimate: {e:#}");
            return;
        }
    };
    println!(
        "\n{} ({}):\n\n| points | GPU estimate, whole (points/s) | its submission (points/s) | unresolved |",
        ctx.caps.device_name, ctx.caps.driver
    );
    println!("|---:|---:|---:|---:|");
    let options = PreprocessOptions {
        progress: false,
        ..Default::default()
    };
    for n in [1_000_000, 10_000_000] {
        let cloud = Cloud {
            normals: None,
            radii: None,
            ..sample::sample_mesh(dragon, n, 1).expect("sampling")
        };
        let mut runs: Vec<(f64, f64, usize)> = (0..RUNS)
            .map(|_| {
                let mut c = cloud.clone();
                let start = Instant::now();
                let t = surfel::knn_gpu::estimate(&ctx, &mut c, &options)
                    .expect("GPU estimate")
                    .expect("estimated");
                (start.elapsed().as_secs_f64(), t.gpu_s, t.unresolved)
            })
            .collect();
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (whole, submission, unresolved) = runs[runs.len() / 2];
        println!(
            "| {n} | {:.2} M | {:.2} M | {unresolved} |",
            n as f64 / whole / 1e6,
            n as f64 / submission / 1e6
        );
    }
}

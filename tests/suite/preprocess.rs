//! The grid k-NN estimation (`scene::preprocess`) against the reference it replaced, one k-d
//! tree query per point: the same neighbour distances for every point, the same radii, and
//! normals within a small angle (only ties between equally distant neighbours and the
//! closed-form eigen solve may differ), on a scanned mesh, a dense mesh and a LiDAR tile.

use crate::common;

use std::path::PathBuf;

use surfel::scene::preprocess::{self, Neighbours, PreprocessOptions, RadiusMode};
use surfel::scene::{self, Cloud};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

fn bare(rel: &str) -> Cloud {
    let cloud = scene::load(&data(rel)).unwrap_or_else(|e| panic!("{e}"));
    Cloud {
        normals: None,
        radii: None,
        faces: None,
        ..cloud
    }
}

#[test]
fn grid_estimation_matches_the_tree_reference() {
    let k = preprocess::DEFAULT_K;
    for rel in [
        "stanford/bun_zipper.ply",
        "stanford/dragon_vrip.ply",
        "lidar/autzen_trim.laz",
    ] {
        let mut cloud = bare(rel);
        let tree = Neighbours::compute_with_tree(&cloud.positions, k);
        let grid = Neighbours::compute(&cloud.positions, k, false);
        for i in 0..cloud.len() {
            assert_eq!(grid.of(i).1, tree.of(i).1, "{rel}: point {i}'s distances");
        }
        let normals = preprocess::estimate_normals(&cloud, &tree, false);
        let radii = preprocess::estimate_radii(&cloud.positions, &tree, RadiusMode::DensitySpacing);
        preprocess::preprocess(
            &mut cloud,
            &PreprocessOptions {
                progress: false,
                ..Default::default()
            },
        );
        assert_eq!(cloud.radii.as_ref(), Some(&radii), "{rel}: radii");
        let d = common::angles(cloud.normals.as_ref().unwrap(), &normals);
        let (median, p99, worst) = (d[d.len() / 2], d[d.len() * 99 / 100], d[d.len() - 1]);
        println!("{rel}: normal angle median {median:.2e}°, 99th {p99:.2e}°, max {worst:.2}°");
        assert!(median < 1e-3, "{rel}: median {median}°");
        assert!(p99 < 0.1, "{rel}: 99th percentile {p99}°");
    }
}

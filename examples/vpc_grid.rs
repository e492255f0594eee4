//! Splits a point cloud into an N x N grid of COPC tiles (by x and y) and writes their
//! virtual point cloud, for the measurements of `docs/measurements.md`:
//!
//!     cargo run --release --example vpc_grid -- CLOUD OUT_DIR [N [NODE_POINTS]]
//!
//! writes `OUT_DIR/tiles/tXXXX.copc.laz` (at most NODE_POINTS points per octree node, default
//! 20,000: every visible tile's root is drawn, so the roots of a 10 x 10 grid should fit a
//! point budget together) and `OUT_DIR/grid.vpc`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use surfel::copc::{convert, vpc};
use surfel::scene::{self, Cloud, Scalar};

/// The points of `cloud` at `indices`, every attribute kept.
fn subset(cloud: &Cloud, indices: &[usize]) -> Cloud {
    let pick = |v: &Vec<_>| indices.iter().map(|&i| v[i]).collect();
    Cloud {
        positions: indices.iter().map(|&i| cloud.positions[i]).collect(),
        normals: cloud.normals.as_ref().map(pick),
        colors: cloud
            .colors
            .as_ref()
            .map(|v| indices.iter().map(|&i| v[i]).collect()),
        radii: cloud
            .radii
            .as_ref()
            .map(|v| indices.iter().map(|&i| v[i]).collect()),
        scalars: cloud
            .scalars
            .iter()
            .map(|s| Scalar {
                name: s.name.clone(),
                values: indices.iter().map(|&i| s.values[i]).collect(),
            })
            .collect(),
        origin: cloud.origin,
        up: cloud.up,
        ..Cloud::default()
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, input, out, rest @ ..] = args.as_slice() else {
        anyhow::bail!("usage: vpc_grid CLOUD OUT_DIR [N]");
    };
    let n: usize = rest.first().map_or(Ok(10), |s| s.parse()).context("N")?;
    let node_points: u32 = rest
        .get(1)
        .map_or(Ok(20_000), |s| s.parse())
        .context("NODE_POINTS")?;
    let cloud = scene::load(&PathBuf::from(input))?;
    let (lo, hi) = cloud.bounds().context("an empty cloud")?;
    let cell = |v: f32, a: f32, b: f32| (((v - a) / (b - a) * n as f32) as usize).min(n - 1);
    let mut cells = vec![Vec::new(); n * n];
    for (i, p) in cloud.positions.iter().enumerate() {
        cells[cell(p.y, lo.y, hi.y) * n + cell(p.x, lo.x, hi.x)].push(i);
    }
    let out = PathBuf::from(out);
    std::fs::create_dir_all(out.join("tiles"))?;
    let vpc_path = out.join("grid.vpc");
    let mut tiles = Vec::new();
    for (k, indices) in cells.iter().enumerate() {
        if indices.is_empty() {
            continue;
        }
        let path = out.join(format!("tiles/t{k:04}.copc.laz"));
        convert::write_with(&subset(&cloud, indices), &path, node_points)?;
        tiles.push(vpc::summarize(&vpc_path, &path)?);
        eprintln!("{}: {} points", path.display(), indices.len());
    }
    vpc::write(&vpc_path, &tiles)?;
    eprintln!("{}: {} tiles", vpc_path.display(), tiles.len());
    Ok(())
}

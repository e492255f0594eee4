//! `surfel sample`: points sampled from a mesh's faces, written as binary PLY.

use std::path::PathBuf;

use anyhow::{Context as _, Result};
use clap::Args;

#[derive(Args, Debug)]
pub struct SampleArgs {
    /// Mesh with faces (ply, obj).
    pub mesh: PathBuf,
    /// Number of points.
    #[arg(long)]
    pub points: usize,
    /// Output binary PLY.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub(super) fn sample(a: SampleArgs) -> Result<()> {
    use crate::scene::sample::{available_memory, check_memory};
    if let Some(available) = available_memory() {
        check_memory(a.points as u64, available)
            .map_err(|e| anyhow::anyhow!("{}: cannot sample: {e}", a.mesh.display()))?;
    }
    let mesh = crate::scene::load(&a.mesh)?;
    let cloud = crate::scene::sample::sample_mesh(&mesh, a.points, a.seed)
        .with_context(|| format!("{}: cannot sample", a.mesh.display()))?;
    crate::scene::ply::save(&a.out, &cloud)
        .with_context(|| format!("{}: cannot write", a.out.display()))?;
    eprintln!("{} points -> {}", cloud.len(), a.out.display());
    Ok(())
}

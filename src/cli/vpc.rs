//! `surfel vpc`: a virtual point cloud (.vpc) listing COPC, LAS or LAZ files, from their
//! headers.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use crate::copc::tiles;

#[derive(Args, Debug)]
pub struct VpcArgs {
    /// The files to list: files, folders (their .copc.laz files) and glob patterns such as
    /// 'tiles/*.copc.laz'.
    #[arg(required = true, value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// The virtual point cloud to write (name ending in .vpc); its hrefs are relative to its
    /// folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Folders given as inputs contribute their subfolders' files too.
    #[arg(long)]
    pub recursive: bool,
}

pub(super) fn vpc(a: VpcArgs) -> Result<()> {
    if !crate::copc::vpc::is_vpc(&a.out.to_string_lossy()) {
        bail!(
            "{}: a virtual point cloud's name ends in .vpc (readers choose the format by it)",
            a.out.display()
        );
    }
    let files = tiles::expand(&a.inputs, &["copc.laz"], a.recursive)?;
    let crs: Vec<Option<String>> = files.iter().map(|f| tiles::input_crs(f)).collect();
    if let Some(warning) = tiles::mixed_crs_warning(&files, &crs) {
        eprintln!("warning: {warning}");
    }
    let summaries = files
        .iter()
        .map(|f| tiles::summarize(&a.out, f, None))
        .collect::<Result<Vec<_>>>()?;
    crate::copc::vpc::write(&a.out, &summaries)?;
    let points: u64 = summaries.iter().map(|s| s.points).sum();
    eprintln!(
        "{}: {} files, {points} points",
        a.out.display(),
        summaries.len()
    );
    Ok(())
}

//! `surfel convert`: inputs written as one COPC file for streaming, or each as its own COPC
//! tile with a virtual point cloud listing them (`--tiles`).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{bail, Context as _, Result};
use clap::Args;

use crate::copc::convert::{self, ConvertOptions, DEFAULT_NODE_POINTS};
use crate::copc::tiles::{self, Done, Tile};
use crate::scene::ReadOptions;

#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// Input clouds (ply, las, laz, copc.laz, e57, pcd, obj, xyz, txt, pts, csv): files,
    /// folders (their files in these formats) and glob patterns such as 'tiles/*.laz'.
    #[arg(required = true, value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// Output: the COPC file (name ending in .copc.laz); with --tiles, the folder of the tiles.
    #[arg(long)]
    pub out: PathBuf,
    /// Folders given as inputs contribute their subfolders' files too.
    #[arg(long)]
    pub recursive: bool,
    /// Convert each input into its own COPC file NAME.copc.laz in the --out folder, in
    /// parallel, and list them in a virtual point cloud (.vpc) there.
    #[arg(long)]
    pub tiles: bool,
    /// With --tiles: inputs converted at once, each on an equal share of the cores. Default:
    /// one per core.
    #[arg(long, value_name = "N", requires = "tiles", value_parser = clap::value_parser!(u32).range(1..))]
    pub jobs: Option<u32>,
    /// With --tiles: the virtual point cloud's name, written as NAME.vpc in the --out folder
    /// (listing the tiles that converted). Default: the folder's name.
    #[arg(long, value_name = "NAME", requires = "tiles")]
    pub vpc: Option<String>,
    /// Target points per octree node (one LAZ chunk each).
    #[arg(long, default_value_t = DEFAULT_NODE_POINTS, value_name = "N")]
    pub node_points: u32,
    /// Text inputs without a row of column names: name the columns (see `surfel render`).
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
}

/// Set by SIGINT or SIGTERM: the conversion stops and removes its temporary files.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn request_stop(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

/// Makes the first SIGINT (Ctrl-C) or SIGTERM set [`STOP`]; a second one ends the process at
/// once (the handler resets itself).
fn stop_on_signals() {
    #[cfg(unix)]
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe; the action
        // is fully initialised before it is installed.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = request_stop as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESETHAND;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

pub(super) fn convert(a: ConvertArgs) -> Result<()> {
    let options = ConvertOptions {
        node_points: a.node_points,
        read: ReadOptions {
            budget: None,
            columns: a.columns.clone(),
        },
        stop: Some(&STOP),
    };
    let inputs = tiles::expand(&a.inputs, &tiles::FORMATS, a.recursive)?;
    stop_on_signals();
    if a.tiles {
        return convert_tiles(&a, &inputs, &options);
    }
    // A merge into one of its inputs (a folder converted twice) would take in the old output.
    if let Some(input) = inputs
        .iter()
        .find(|i| inputs.len() > 1 && same_file(i, &a.out))
    {
        bail!(
            "{}: the output is also one of the {} inputs; choose another --out",
            input.display(),
            inputs.len()
        );
    }
    if let Some(warning) = tiles::check_one_crs(&inputs)? {
        eprintln!("warning: {warning}");
    }
    let stats = convert::convert_many(&inputs, &a.out, &options)?;
    for warning in &stats.warnings {
        eprintln!("warning: {warning}");
    }
    eprintln!(
        "{} points -> {} ({:.1} MB, {:.1} bytes per point, {} nodes): read in {:.2} s, octree built in {:.2} s, compressed and written in {:.2} s; {:.2} M points/s in all",
        stats.points,
        a.out.display(),
        stats.bytes as f64 / 1e6,
        stats.bytes as f64 / stats.points.max(1) as f64,
        stats.nodes,
        stats.load_seconds,
        stats.build_seconds,
        stats.write_seconds - stats.build_seconds,
        rate(stats.points, stats.load_seconds + stats.write_seconds),
    );
    Ok(())
}

/// Millions of `points` per second over `seconds`.
fn rate(points: u64, seconds: f64) -> f64 {
    points as f64 / seconds.max(1e-9) / 1e6
}

/// `--tiles`: each input into its own COPC file in the `--out` folder, a line per finished
/// tile and a total line; fails at the end, naming them, when tiles failed.
fn convert_tiles(a: &ConvertArgs, inputs: &[PathBuf], options: &ConvertOptions) -> Result<()> {
    let dir = &a.out;
    if dir.is_file() {
        bail!(
            "{}: --tiles writes into a folder, and this is a file",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let plan = tiles::plan(inputs, dir);
    for tile in &plan {
        if same_file(&tile.input, &tile.out) {
            bail!(
                "{}: its tile would overwrite it; choose another --out folder",
                tile.input.display()
            );
        }
    }
    let crs: Vec<Option<String>> = inputs.iter().map(|p| tiles::input_crs(p)).collect();
    if let Some(warning) = tiles::mixed_crs_warning(inputs, &crs) {
        eprintln!("warning: {warning}");
    }
    let jobs = a.jobs.map_or_else(tiles::default_jobs, |j| j as usize);
    let start = std::time::Instant::now();
    let (total, mut finished) = (plan.len(), 0);
    let results = tiles::convert_tiles(&plan, options, jobs, |done: &Done| {
        finished += 1;
        match &done.result {
            Ok(stats) => {
                for warning in &stats.warnings {
                    eprintln!("warning: {warning}");
                }
                eprintln!(
                    "[{finished}/{total}] {}: {} points in {:.2} s ({:.2} M points/s)",
                    done.tile.name,
                    stats.points,
                    done.seconds,
                    rate(stats.points, done.seconds)
                );
            }
            Err(e) => eprintln!("[{finished}/{total}] {}: failed: {e:#}", done.tile.name),
        }
    });
    let converted: Vec<(&Tile, u64)> = results
        .iter()
        .flatten()
        .filter_map(|d| d.result.as_ref().ok().map(|s| (d.tile, s.points)))
        .collect();
    let points: u64 = converted.iter().map(|(_, p)| p).sum();
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "{} of {total} tiles, {points} points in {seconds:.2} s ({:.2} M points/s, {jobs} jobs) -> {}",
        converted.len(),
        rate(points, seconds),
        dir.display()
    );
    if !converted.is_empty() && !STOP.load(Ordering::Relaxed) {
        let vpc = tiles::vpc_path(dir, a.vpc.as_deref());
        let summaries = converted
            .iter()
            .map(|(tile, _)| tiles::summarize(&vpc, &tile.out, Some(&tile.input)))
            .collect::<Result<Vec<_>>>()?;
        crate::copc::vpc::write(&vpc, &summaries)?;
        eprintln!("{}: {} tiles", vpc.display(), summaries.len());
    }
    if STOP.load(Ordering::Relaxed) {
        bail!("interrupted after {} of {total} tiles", converted.len());
    }
    let failed: Vec<String> = results
        .iter()
        .flatten()
        .filter(|d| d.result.is_err())
        .map(|d| d.tile.input.display().to_string())
        .collect();
    if !failed.is_empty() {
        bail!(
            "{} of {total} tiles failed: {}",
            failed.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// Whether `a` and `b` are one existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

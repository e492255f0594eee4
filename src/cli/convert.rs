//! `surfel convert`: any input written as a COPC file for streaming.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use clap::Args;

use crate::scene::ReadOptions;
use crate::stream::convert::{self, ConvertOptions, DEFAULT_NODE_POINTS};

#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// Input cloud (ply, las, laz, copc.laz, e57, pcd, obj, xyz, txt, pts, csv).
    pub input: PathBuf,
    /// Output COPC file (name ending in .copc.laz).
    #[arg(long)]
    pub out: PathBuf,
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
            columns: a.columns,
        },
        stop: Some(&STOP),
    };
    stop_on_signals();
    let stats = convert::convert(&a.input, &a.out, &options)?;
    for warning in &stats.warnings {
        eprintln!("warning: {warning}");
    }
    let rate = |s: f64| stats.points as f64 / s.max(1e-9) / 1e6;
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
        rate(stats.load_seconds + stats.write_seconds),
    );
    Ok(())
}

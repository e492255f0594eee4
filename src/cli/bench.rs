//! `surfel bench` and `surfel report`: the evaluation sweeps and their reports.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use clap::{Args, Subcommand};

use super::context;

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub action: Option<BenchAction>,
    /// Sweep file (TOML); see benches/sweeps/.
    #[arg(required_unless_present = "quick")]
    pub sweep: Option<PathBuf>,
    /// Run the tiny built-in sweep (benches/sweeps/quick.toml), suitable for CI on lavapipe.
    #[arg(long, conflicts_with = "sweep")]
    pub quick: bool,
    /// Output folder for results.json, results.csv and charts/.
    #[arg(long, default_value = "bench-out")]
    pub out: PathBuf,
    /// Also write report.md into the output folder.
    #[arg(long)]
    pub report: bool,
    #[arg(long)]
    pub validation: bool,
}

/// What `surfel bench` does besides running a sweep.
#[derive(Subcommand, Debug)]
pub enum BenchAction {
    /// Compare two timing results (`render --timings` files or bench results.json): per
    /// configuration and pass, B's median over A's with its bootstrap 95 % interval; `*` marks
    /// a difference beyond noise (an interval without 1).
    Compare { a: PathBuf, b: PathBuf },
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// results.json written by `surfel bench`.
    pub results: PathBuf,
    /// Output folder (default: the folder of results.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub(super) fn bench(a: BenchArgs) -> Result<()> {
    use crate::eval::config::BenchConfig;
    if let Some(BenchAction::Compare { a, b }) = &a.action {
        use crate::eval::compare;
        let rows = compare::compare(&compare::load(a)?, &compare::load(b)?)?;
        print!("{}", compare::table(&rows));
        let beyond = rows.iter().filter(|r| r.differs()).count();
        eprintln!("{beyond} of {} passes differ beyond noise", rows.len());
        return Ok(());
    }
    let config = match &a.sweep {
        Some(path) => BenchConfig::load(path)?,
        None => BenchConfig::quick()?,
    };
    let ctx = context(a.validation)?;
    let out = crate::eval::bench::run(&ctx, &config, &a.out, true)?;
    if ctx.validation && ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors", ctx.validation_errors());
    }
    eprintln!(
        "{} records -> {}, {}, {} charts",
        out.results.records.len(),
        out.json.display(),
        out.csv.display(),
        out.charts.len()
    );
    if a.report {
        let path = crate::eval::report::write_report(&out.results, &out.json, &a.out)?;
        eprintln!("report -> {}", path.display());
    }
    Ok(())
}

pub(super) fn report(a: ReportArgs) -> Result<()> {
    let results = crate::eval::results::Results::read_json(&a.results)?;
    let out = a.out.unwrap_or_else(|| {
        a.results
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default()
    });
    // The wide table the report links: every number of every record, in the current columns.
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    results.write_csv(&out.join("results.csv"))?;
    let path = crate::eval::report::write_report(&results, &a.results, &out)?;
    eprintln!("report -> {}", path.display());
    Ok(())
}

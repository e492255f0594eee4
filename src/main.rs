use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = surfel::cli::Cli::parse();
    match surfel::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

//! `sim-server`: runs one simbus world.

use std::process::ExitCode;

use clap::Parser;
use sim_server::cli::{init_logging, run, ServerArgs};

fn main() -> ExitCode {
    let args = ServerArgs::parse();
    init_logging(args.verbose);
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("sim-server: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

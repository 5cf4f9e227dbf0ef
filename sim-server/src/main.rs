//! `sim-server`: runs one simbus world.

mod cli;
#[cfg(test)]
mod doc_commands;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    cli::main(cli::ServerArgs::parse())
}

//! `soundloc`: the command line. It parses, wires library objects and prints; all
//! behaviour lives in the `soundloc` library.

mod cmd;
mod serve;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cmd::Cli::parse();
    match cmd::run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("soundloc: error: {e:#}");
            ExitCode::from(2)
        }
    }
}

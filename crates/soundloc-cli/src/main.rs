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
        // A closed pipe on stdout (`soundloc … | head`) is the reader's choice, not an error.
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            }) =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("soundloc: error: {e:#}");
            ExitCode::from(2)
        }
    }
}

//! `soundloc`: the command line. It parses, wires library objects and prints; all
//! behaviour lives in the `soundloc` library.

mod cmd;
mod serve;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    init_log();
    cmd::input::install_signal_handler();
    // This thread pushes the audio: as one of the pool's workers it runs each push
    // itself instead of handing it over and sleeping (`soundloc::pool`).
    soundloc::pool::adopt_current_thread();
    let cli = cmd::Cli::parse();
    match cmd::run(cli) {
        Ok(code) => code,
        // A closed pipe on stdout (`soundloc … | head`) is the reader's choice, not an
        // error; a closed FIFO given as an output file is one.
        Err(e) if e.chain().any(|c| c.is::<cmd::sinks::StdoutClosed>()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("soundloc: error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// Diagnostic log on stderr when `SOUNDLOC_LOG` is `error`, `warn`, `info`, `debug` or
/// `trace` (any other value: `debug`): each line stamped with the seconds since start, which shows where a
/// run's time goes (transfer functions, device set-up, kernel compilation, the engine).
fn init_log() {
    let Ok(level) = std::env::var("SOUNDLOC_LOG") else {
        return;
    };
    let level = match level.trim().to_ascii_lowercase().as_str() {
        "" | "0" | "off" => return,
        "error" => tracing::Level::ERROR,
        "warn" => tracing::Level::WARN,
        "info" => tracing::Level::INFO,
        "trace" => tracing::Level::TRACE,
        _ => tracing::Level::DEBUG,
    };
    tracing_subscriber::fmt()
        .with_max_level(level)
        .with_writer(std::io::stderr)
        .with_timer(tracing_subscriber::fmt::time::Uptime::default())
        .with_target(false)
        .with_ansi(false)
        .init();
}

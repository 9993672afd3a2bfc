//! `soundloc-fuzz`: long mutation runs over soundloc's file readers (see the library docs
//! and FUZZING.md). Exit status 1 when any input panicked, hung or was refused without
//! the file being named; panicking inputs are saved in `--crashes`.
//!
//! ```text
//! soundloc-fuzz [--iters N] [--seed S] [--crashes DIR] [TARGET ...]
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut iters = 100_000u64;
    let mut seed = 1u64;
    let mut crashes = PathBuf::from("fuzz-crashes");
    let mut only = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut num = |what: &str| -> u64 {
            args.next().and_then(|v| v.parse().ok()).unwrap_or_else(|| {
                eprintln!("soundloc-fuzz: {what} needs a number");
                std::process::exit(2)
            })
        };
        match a.as_str() {
            "--iters" => iters = num("--iters"),
            "--seed" => seed = num("--seed"),
            "--crashes" => crashes = PathBuf::from(args.next().unwrap_or_default()),
            "-h" | "--help" => {
                let names: Vec<_> = soundloc_fuzz::targets().iter().map(|t| t.name).collect();
                println!(
                    "soundloc-fuzz [--iters N] [--seed S] [--crashes DIR] [TARGET ...]\ntargets: {}",
                    names.join(" ")
                );
                return ExitCode::SUCCESS;
            }
            t => only.push(t.to_string()),
        }
    }
    std::panic::set_hook(Box::new(|_| {}));
    let mut bad = false;
    for t in soundloc_fuzz::targets() {
        if !only.is_empty() && !only.iter().any(|o| o == t.name) {
            continue;
        }
        let start = std::time::Instant::now();
        let r = soundloc_fuzz::run(&t, iters, seed, Some(&crashes));
        println!(
            "{:<14} {:>9} execs in {:>7.1} s: {:>9} accepted, {:>9} refused naming the file, {} refused without, {} panics, {} slower than {:?} (max {:.1} ms)",
            t.name,
            r.execs,
            start.elapsed().as_secs_f64(),
            r.accepted,
            r.refused,
            r.unnamed,
            r.panics.len(),
            r.slow,
            soundloc_fuzz::HANG,
            r.max_exec.as_secs_f64() * 1e3
        );
        for e in r.unnamed_errors.iter().chain(r.panics.iter().take(5)) {
            println!("    {e}");
        }
        bad |= r.unnamed > 0 || !r.panics.is_empty() || r.slow > 0;
    }
    if bad {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

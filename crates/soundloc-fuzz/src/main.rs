//! `soundloc-fuzz`: long mutation runs over soundloc's file readers (see the library docs
//! and FUZZING.md). Exit status 1 when any input panicked, hung or was refused without
//! the file being named; panicking inputs are saved in `--crashes`.
//!
//! ```text
//! soundloc-fuzz [--iters N] [--seed S] [--crashes DIR] [TARGET ...]
//! soundloc-fuzz --write-seeds DIR        (every target's valid files, DIR/<target>/seed-<i>)
//! soundloc-fuzz cli [--bin PATH] [--iters N] [--seed S] [--timeout SECONDS] [--crashes DIR]
//! ```
//!
//! `cli` fuzzes the `soundloc` command line instead (`soundloc_fuzz::cli`): exit status 1
//! when a command line panicked, was killed by a signal or timed out; those command lines
//! are listed in `DIR/cli-findings.txt`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

fn main() -> ExitCode {
    let mut iters = 100_000u64;
    let mut seed = 1u64;
    let mut crashes = PathBuf::from("fuzz-crashes");
    let mut only = Vec::new();
    let mut bin = None;
    let mut timeout = 5u64;
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
            "--timeout" => timeout = num("--timeout"),
            "--bin" => bin = args.next().map(PathBuf::from),
            "--write-seeds" => {
                let dir = PathBuf::from(args.next().unwrap_or_default());
                return match soundloc_fuzz::write_seeds(&dir) {
                    Ok(n) => {
                        println!("{n} seed files in {}", dir.display());
                        ExitCode::SUCCESS
                    }
                    Err(e) => {
                        eprintln!("soundloc-fuzz: {}: {e}", dir.display());
                        ExitCode::from(2)
                    }
                };
            }
            "-h" | "--help" => {
                let names: Vec<_> = soundloc_fuzz::targets().iter().map(|t| t.name).collect();
                println!(
                    "soundloc-fuzz [--iters N] [--seed S] [--crashes DIR] [TARGET ...]\n\
                     soundloc-fuzz --write-seeds DIR\n\
                     soundloc-fuzz cli [--bin PATH] [--iters N] [--seed S] [--timeout SECONDS] [--crashes DIR]\n\
                     targets: {}",
                    names.join(" ")
                );
                return ExitCode::SUCCESS;
            }
            t => only.push(t.to_string()),
        }
    }
    if only.iter().any(|o| o == "cli") {
        return cli(bin, iters, seed, timeout, &crashes);
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

fn cli(bin: Option<PathBuf>, iters: u64, seed: u64, timeout: u64, crashes: &Path) -> ExitCode {
    use soundloc_fuzz::cli;
    let Some(bin) = bin.or_else(cli::find_binary) else {
        eprintln!("soundloc-fuzz: no soundloc binary: build it (cargo build --release -p soundloc-cli), or give --bin or SOUNDLOC_BIN");
        return ExitCode::from(2);
    };
    let start = std::time::Instant::now();
    let mut last = std::time::Instant::now();
    let r = cli::fuzz_cli(&bin, iters, seed, Duration::from_secs(timeout), |r| {
        if last.elapsed() > Duration::from_secs(30) {
            last = std::time::Instant::now();
            eprintln!(
                "  {} command lines, {:.0} s: {} panics, {} signals, {} time-outs",
                r.execs,
                start.elapsed().as_secs_f64(),
                r.panics,
                r.signals,
                r.timeouts
            );
        }
    });
    println!(
        "cli: {} command lines in {:.1} s ({}, seed {seed}, {timeout} s limit): {}",
        r.execs,
        start.elapsed().as_secs_f64(),
        bin.display(),
        r.counts()
    );
    let mut text = String::new();
    for f in &r.findings {
        text.push_str(&format!(
            "{:?} ({}): {}\n{}\n\n",
            f.outcome,
            f.status,
            f.command_line(),
            f.stderr
        ));
    }
    if !r.findings.is_empty() {
        print!("{text}");
        let _ = std::fs::create_dir_all(crashes);
        let p = crashes.join("cli-findings.txt");
        if std::fs::write(&p, &text).is_ok() {
            println!("findings written to {}", p.display());
        }
    }
    if r.bad() > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

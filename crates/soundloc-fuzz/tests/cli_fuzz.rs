//! The suite's command-line fuzzing: every seed command line runs cleanly, then 200 seeded
//! mutations of them run against the release binary with no panic, no death by a signal and
//! no time-out. Skipped (with a line saying so) when the binary is not built: `SOUNDLOC_BIN`,
//! else `target/release/soundloc`.

use soundloc_fuzz::cli::{self, Outcome};
use std::time::Duration;

#[test]
fn cli_fuzz() {
    let Some(bin) = cli::find_binary() else {
        println!("SKIPPED cli_fuzz: soundloc binary not built");
        return;
    };
    let files = cli::input_files();
    let work = std::env::temp_dir().join(format!("soundloc-cli-fuzz-test-{}", std::process::id()));
    let mut failures = Vec::new();
    for (_, s) in cli::seed_command_lines() {
        let args: Vec<String> = s.iter().map(|a| a.to_string()).collect();
        assert!(cli::is_safe(&args), "{args:?}");
        let (outcome, status, stderr, _) = cli::run_once(&bin, &work, &files, &args, Duration::from_secs(20));
        if outcome != Outcome::Ok {
            failures.push(format!("{} → {outcome:?} ({status}): {stderr}", s.join(" ")));
        }
    }
    let _ = std::fs::remove_dir_all(&work);
    assert!(
        failures.is_empty(),
        "seed command lines fail:\n{}",
        failures.join("\n")
    );

    let iters = std::env::var("SOUNDLOC_CLI_FUZZ_ITERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let r = cli::fuzz_cli(&bin, iters, 20261126, Duration::from_secs(5), |_| {});
    println!("cli: {} command lines: {}", r.execs, r.counts());
    assert_eq!(r.execs, iters);
    assert!(
        r.ok > 0 && r.clean_errors > 0,
        "the mutations should make both good and bad command lines"
    );
    let bad: Vec<String> = r
        .findings
        .iter()
        .filter(|f| matches!(f.outcome, Outcome::Panic | Outcome::Signal | Outcome::Timeout))
        .map(|f| {
            format!(
                "{:?} ({}): {}\n{}",
                f.outcome,
                f.status,
                f.command_line(),
                f.stderr
            )
        })
        .collect();
    assert_eq!(r.bad(), 0, "{}", bad.join("\n\n"));
}

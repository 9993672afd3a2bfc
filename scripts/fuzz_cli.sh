#!/usr/bin/env bash
# Fuzzing of the soundloc command line (see FUZZING.md):
#   scripts/fuzz_cli.sh [N] [SEED]     (default 20000 command lines, seed 20261126)
# Mutated command lines run against target/release/soundloc (or $SOUNDLOC_BIN), each in a
# fresh temporary folder with a 5 s time limit and a 4 GiB address-space limit. Exit status 1
# when a command line panicked, died by a signal or timed out; they are listed in
# fuzz-crashes/cli-findings.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
n="${1:-20000}"; seed="${2:-20261126}"
bin="${SOUNDLOC_BIN:-$PWD/target/release/soundloc}"
[ -x "$bin" ] || nice -n 19 cargo build --release -q -p soundloc-cli
nice -n 19 cargo build --release -q -p soundloc-fuzz
exec nice -n 19 target/release/soundloc-fuzz cli --bin "$bin" --iters "$n" --seed "$seed" --timeout 5 --crashes fuzz-crashes

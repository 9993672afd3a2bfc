#!/usr/bin/env bash
# Long mutation-fuzzing run over every file reader (see FUZZING.md):
#   scripts/fuzz.sh [ITERS] [SEED] [TARGET ...]     (default 1000000 per target, seed 20261125)
# Runs under a 4 GiB address-space limit; panicking inputs are saved in fuzz-crashes/.
set -euo pipefail
cd "$(dirname "$0")/.."
iters="${1:-1000000}"; seed="${2:-20261125}"; shift $(( $# > 2 ? 2 : $# ))
cargo build --release -q -p soundloc-fuzz
exec prlimit --as=4294967296 target/release/soundloc-fuzz --iters "$iters" --seed "$seed" --crashes fuzz-crashes "$@"

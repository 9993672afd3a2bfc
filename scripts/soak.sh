#!/usr/bin/env bash
# One-hour soak of the stream engine: 60 minutes of 8-channel audio pushed in 10 ms
# blocks (PAST windows, PERIOD 10, GEVD with K from the first second, tracking on);
# prints the result count and resident memory after 1 minute and at the end.
# Usage: scripts/soak.sh [MINUTES]   (default 60)
set -euo pipefail
cd "$(dirname "$0")/.."
SOUNDLOC_SOAK_MINUTES="${1:-60}" cargo test --release -p soundloc --test soak -- --nocapture 2>&1 | grep -E "soak:|test result"

#!/usr/bin/env bash
# Every test suite, installing what the suites need first (Debian packages).
#   Rust: the workspace, with live-microphone capture compiled in (needs libasound2-dev).
# Tests that need hardware this machine lacks (GPU, capture device) print
# "SKIPPED <test>: <reason>".
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
pkg-config --exists alsa 2>/dev/null || need+=(libasound2-dev pkg-config)
if ((${#need[@]})); then
    echo "scripts/test.sh: installing ${need[*]}" >&2
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi
cargo test --release --workspace --features soundloc-cli/capture "$@"

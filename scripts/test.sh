#!/usr/bin/env bash
# Every test suite, installing what the suites need first (Debian and PyPI packages).
#   Rust: the workspace, with live-microphone capture compiled in (needs libasound2-dev).
#   Browser: the live view (--serve) in headless Chromium through chromedriver (Debian
#   chromium + chromium-driver), driven by crates/soundloc-cli/tests/cli_live.rs.
#   Python: the binding's wheel built with maturin into a virtual environment
#   (target/pyvenv, with numpy and pytest), then pytest.
# Tests that need hardware or programs this machine lacks (GPU, capture device, browser) print
# "SKIPPED <test>: <reason>".
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
pkg-config --exists alsa 2>/dev/null || need+=(libasound2-dev pkg-config)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v chromedriver >/dev/null 2>&1 || need+=(chromium-driver)
if ((${#need[@]})); then
    echo "scripts/test.sh: installing ${need[*]}" >&2
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi
cargo test --release --workspace --features soundloc-cli/capture "$@"

venv=target/pyvenv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.5,<2" numpy pytest "pyroomacoustics>=0.8" "ray[data]>=2.9"
rm -rf target/wheels
"$venv/bin/maturin" build --release -q -m crates/soundloc-py/Cargo.toml -o target/wheels -i "$venv/bin/python"
"$venv/bin/python" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels/soundloc-*.whl
SOUNDLOC_BIN="$PWD/target/release/soundloc" "$venv/bin/python" -m pytest -q -rs crates/soundloc-py/tests

#!/usr/bin/env bash
# Regenerate the kernel bundles embedded in the binary (crates/soundloc/kernels/prebuilt/
# sm_*.bin; backend/cuda/prebuilt.rs) after a kernel edit. No GPU is needed: NVRTC comes
# from PyPI. Builds the release binary, compiles every bundle, rebuilds with them.
#   scripts/cuda_prebuild.sh [ARCH...]      (default: every bundle the binary embeds)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
archs="${*:-sm_75 sm_80 sm_90 sm_100 sm_120}"
venv="${NVRTC_VENV:-target/nvrtc-venv}"
lib="$venv/lib/python3.11/site-packages/nvidia/cu13/lib"
if [ ! -e "$lib/libnvrtc.so.13" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q "nvidia-cuda-nvrtc==13.0.88"
  lib="$(echo "$venv"/lib/python3*/site-packages/nvidia/cu13/lib)"
fi
cargo build --release -q
cp target/release/soundloc target/soundloc-prebuild
for a in $archs; do
  LD_LIBRARY_PATH="$lib" target/soundloc-prebuild cuda-prebuild --arch "$a" \
    -o "crates/soundloc/kernels/prebuilt/$a.bin" 2>&1 | tail -n 1
done
rm -f target/soundloc-prebuild
cargo build --release -q

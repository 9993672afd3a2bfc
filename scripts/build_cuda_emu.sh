#!/usr/bin/env bash
# Build the CPU emulator of the CUDA kernels (one library per Jacobi layout variant) into
# target/cuda-emu/. The GPU parity tests use it when SOUNDLOC_CUDA_EMU_DIR points there:
#   scripts/build_cuda_emu.sh && SOUNDLOC_CUDA_EMU_DIR=$PWD/target/cuda-emu \
#     cargo test -p soundloc --test gpu_parity
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
k="$root/crates/soundloc/kernels"
out="${1:-$root/target/cuda-emu}"
mkdir -p "$out"
for v in "4 4" "4 8" "4 16" "8 16" "16 16"; do
  set -- $v
  g++ -O2 -g -std=c++17 -fPIC -shared -DSOUNDLOC_EMU -DSL_LPP=$1 -DSL_RPL=$2 -I "$k" \
    "$k/emu/emu.cpp" -o "$out/libsoundloc_emu_l$1_r$2.so" &
done
wait
ls -l "$out"

#!/usr/bin/env bash
# Device-side run of the CUDA backend's checks and benchmarks (see docs/gpu.md).
#
# Build here first (no Rust on the device), then carry .devcarry/:
#   cargo build --release && cargo test --release -p soundloc --test gpu_parity --no-run
#   scripts/gpu_run.sh --stage        # copies the binaries and the peer into .devcarry/
# On the device (repo root, $OUT set by the device tool):
#   scripts/gpu_run.sh [parity] [bench] [stream] [streams] [peer] [bigbatch] [f64] [e2e] [robust] [multi] [newalg] [prebuild]   (default: parity bench peer)
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
C="$root/.devcarry"
if [ "${1:-}" = "--stage" ]; then
  mkdir -p "$C"
  cp "$root/target/release/soundloc" "$C/soundloc"
  t=$(ls -t "$root"/target/release/deps/gpu_parity-* | grep -v '\.d$' | head -1)
  cp "$t" "$C/gpu_parity"
  cp "${PEER:-$root/../shared/bench/peer_torch_gsvd.py}" "$C/peer_torch_gsvd.py"
  ls -la "$C"; du -sh "$C"; exit 0
fi
OUT="${OUT:-/tmp/gpu_out}"; mkdir -p "$OUT"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
if ! ls /usr/local/cuda/lib64/libnvrtc.so* >/dev/null 2>&1; then
  n=$(python3 -c 'import nvidia.cu13, os; print(os.path.join(os.path.dirname(nvidia.cu13.__file__), "lib"))' 2>/dev/null)
  [ -n "$n" ] && export LD_LIBRARY_PATH="$n:$LD_LIBRARY_PATH"
fi
steps="${*:-parity bench peer}"
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,memory.used --format=csv | tee "$OUT/gpu.txt"
echo "LD_LIBRARY_PATH=$LD_LIBRARY_PATH"
for s in $steps; do
  case $s in
    parity)
      SOUNDLOC_CUDA_DEBUG=1 SOUNDLOC_REQUIRE_GPU=1 "$C/gpu_parity" --nocapture --test-threads=1 --skip kernels_compile 2>&1 | tee "$OUT/parity.log" | grep -v "^$" ;;
    bench)
      for b in ${BENCH_BATCHES:-64 256 1024}; do
        "$C/soundloc" bench --device cuda --algorithm gsvd --algorithm gevd --batch $b --repeats 10 --json
      done 2>&1 | tee "$OUT/bench.jsonl" ;;
    ab)
      # A/B of tuning knobs, batch 256 (AB_VARIANTS overrides): the Jacobi kernel instead of
      # the tridiagonal eigensolver; five 128-thread eigensolver blocks per SM; bisection to full
      # precision; 256-thread eigensolver blocks at Ns = 2.
      for v in ${AB_VARIANTS:-SOUNDLOC_CUDA_DEC=jacobi SOUNDLOC_CUDA_NVRTC_OPTS=-DEH_NARROW_MINB=5 SOUNDLOC_CUDA_NVRTC_OPTS=-DEH_BTOL=0.0 SOUNDLOC_CUDA_EIGH_THREADS=256}; do
        echo "== $v"
        env "$v" "$C/soundloc" bench --device cuda --algorithm gsvd --algorithm gevd --batch ${AB_BATCH:-256} --repeats 10 --json
      done 2>&1 | tee "$OUT/ab.jsonl" ;;
    prof)
      # Cycle counts per phase of the tridiagonal eigensolver (eigh.cu), one window and batched.
      for b in 1 256; do
        SOUNDLOC_CUDA_PROFILE=1 "$C/soundloc" bench --device cuda --algorithm gsvd --algorithm sevd --batch $b --repeats 3 --json 2>&1 | grep -E "eigh cycles" | sort | uniq -c | sort -rn | head -4
      done 2>&1 | tee "$OUT/prof.txt" ;;
    stream)
      # The stream engine under 10 ms pushes, PERIOD 1: real-time factor and latency.
      "$C/soundloc" bench --stream --device cuda --array ring8 --array seed --algorithm gsvd --algorithm gevd --seconds ${STREAM_SECONDS:-5} 2>&1 | tee "$OUT/stream.txt" ;;
    streams)
      # Many streams on one GPU (issue 8): N seed-config PERIOD-1 streams in one group,
      # 10 ms ticks; real-time factor below 1 = all N kept in real time.
      for a in seed ring8; do
        ns="${STREAMS_SEED:-1 50 100 150 200 250}"; [ $a = ring8 ] && ns="${STREAMS_RING:-1 200 1000}"
        args=""; for n in $ns; do args="$args --streams $n"; done
        "$C/soundloc" bench --stream --device ${STREAMS_DEVICE:-cuda} --array $a --algorithm gsvd --seconds ${STREAM_SECONDS:-3} $args
      done 2>&1 | tee "$OUT/streams.txt" ;;
    e2e)
      # End to end (issue 10): a 60-mic, 2522-direction TF zip and 60 s of 60-channel
      # 16-bit audio made here, GSVD PERIOD 1 on the GPU: cold (no cache) and warm.
      # E2E_DIR inside the repo (e.g. target/sl_e2e) survives between calls on a warm machine.
      W=${E2E_DIR:-/tmp/sl_e2e}; mkdir -p $W; W=$(cd $W && pwd); export SOUNDLOC_CACHE_DIR=$W/cache
      [ -f $W/tf.zip ] || "$C/soundloc" tf make --builtin sphere60 --grid sphere:2522 -o $W/tf.zip
      [ -f $W/rec.wav ] || python3 -c "
import os, struct
n = 60 * 16000 * 60 * 2
h = b'RIFF' + struct.pack('<I', 36 + n) + b'WAVEfmt ' + struct.pack('<IHHIIHH', 16, 1, 60, 16000, 16000 * 120, 120, 16) + b'data' + struct.pack('<I', n)
f = open('$W/rec.wav', 'wb'); f.write(h)
for _ in range(60): f.write(os.urandom(16000 * 120))
"
      for run in cold warm warm; do
        extra=""; [ $run = cold ] && extra="--no-cache"
        # Each run's debug timeline (driver, kernels, context) goes to $OUT/e2e_$run.log
        # (cold, and the second warm run's).
        SOUNDLOC_LOG=debug python3 -c "
import resource, subprocess, sys, time
t = time.time(); r = subprocess.run(sys.argv[2:], stdout=open('$W/out.jsonl', 'w'), stderr=open('$OUT/e2e_' + sys.argv[1] + '.log', 'w'))
print(sys.argv[1] + ': %.2f s wall, %d KB max RSS, exit %d' % (time.time() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode))
" $run "$C/soundloc" localize $W/rec.wav --tf $W/tf.zip --noise-range 0:1 --algorithm gsvd --period 1 --device cuda -q $extra
        wc -l < $W/out.jsonl
      done 2>&1 | tee "$OUT/e2e.txt"
      "$C/soundloc" bench --e2e --tf $W/tf.zip --input $W/rec.wav --algorithm gsvd --period 1 --device cuda 2>&1 | tee -a "$OUT/e2e.txt"
      "$C/soundloc" bench --e2e --tf $W/tf.zip --input $W/rec.wav --algorithm gsvd --period 50 --device cpu 2>&1 | tee -a "$OUT/e2e.txt" ;;
    prebuild)
      # The kernel bundle for this device's architecture (crates/soundloc/kernels/prebuilt/;
      # scripts/cuda_prebuild.sh makes them all without a GPU).
      a=sm_$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader | head -1 | tr -d .)
      "$C/soundloc" cuda-prebuild --arch $a -o "$OUT/$a.bin" 2>&1 | tee "$OUT/prebuild.txt" ;;
    robust)
      # The robust default (no --algorithm: textbook GEVD, subspace M/2, onset weighting on
      # the host) on the e2e files, PERIOD 1 on the GPU, against --onset 0 and the textbook
      # GEVD; run `e2e` first (it makes the files and warms the caches).
      W=${E2E_DIR:-/tmp/sl_e2e}; W=$(cd $W && pwd); export SOUNDLOC_CACHE_DIR=$W/cache
      for round in 1 2; do
        for extra in "" "--onset 0" "--algorithm gevd"; do
          python3 -c "
import resource, subprocess, sys, time
t = time.time(); r = subprocess.run(sys.argv[2:], stdout=open('$W/robust.jsonl', 'w'))
print(sys.argv[1] + ': %.2f s wall, %d KB max RSS, exit %d' % (time.time() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode))
" "robust [$extra] round $round" env SOUNDLOC_LOG=debug "$C/soundloc" localize $W/rec.wav --tf $W/tf.zip --noise-range 0:1 --period ${ROBUST_PERIOD:-1} --device cuda -q $extra 2>&1 | grep -E "round|input done"
          wc -l < $W/robust.jsonl
        done
      done 2>&1 | tee "$OUT/robust.txt" ;;
    multi)
      # Several GPUs (issue 14): throughput on 1, 2, 4 GPUs in one call, and a recording
      # localized on one GPU and on all of them (results must be identical).
      n=$(nvidia-smi -L | wc -l); echo "GPUs: $n" | tee "$OUT/multi.txt"
      lists="cuda:0"; [ $n -ge 2 ] && lists="$lists cuda:0,1"; [ $n -ge 4 ] && lists="$lists cuda:0,1,2,3"
      for d in $lists; do
        for b in ${MULTI_BATCHES:-1024 4096}; do
          "$C/soundloc" bench --device $d --algorithm gsvd --batch $b --repeats 5 --json
        done
      done 2>&1 | tee -a "$OUT/multi.txt"
      W=/tmp/sl_multi; mkdir -p $W
      "$C/soundloc" tf make --builtin sphere60 --grid sphere:642 -o $W/tf.zip
      python3 -c "
import os, struct
n = 20 * 16000 * 60 * 2
f = open('$W/rec.wav', 'wb')
f.write(b'RIFF' + struct.pack('<I', 36 + n) + b'WAVEfmt ' + struct.pack('<IHHIIHH', 16, 1, 60, 16000, 16000 * 120, 120, 16) + b'data' + struct.pack('<I', n))
for _ in range(20): f.write(os.urandom(16000 * 120))
"
      for d in cuda:0 cuda:all; do
        s=$EPOCHREALTIME
        "$C/soundloc" localize $W/rec.wav --tf $W/tf.zip --noise-range 0:1 --algorithm gsvd --period 1 --device $d -q --no-cache > $W/out-$d.jsonl
        echo "$d: $(wc -l < $W/out-$d.jsonl) results in $(python3 -c "print(round($EPOCHREALTIME - $s, 2))") s"
      done 2>&1 | tee -a "$OUT/multi.txt"
      python3 - "$W/out-cuda:0.jsonl" "$W/out-cuda:all.jsonl" <<'PY' 2>&1 | tee -a "$OUT/multi.txt"
import json, sys
a, b = ([json.loads(l) for l in open(p)] for p in sys.argv[1:3])
same = sum([s['grid_index'] for s in x['sources']] == [s['grid_index'] for s in y['sources']] for x, y in zip(a, b))
d = max((abs(s['power_db'] - t['power_db']) for x, y in zip(a, b) for s, t in zip(x['sources'], y['sources'])), default=0)
print(f"1 GPU vs all: {len(a)} and {len(b)} results, identical peaks in {same}, max |dB difference| {d:.2e}")
PY
      ;;
    f64)
      "$C/soundloc" bench --device cuda --precision f64 --algorithm gsvd --algorithm gevd --batch 64 --repeats 5 --json 2>&1 | tee -a "$OUT/bench.jsonl" ;;
    newalg)
      # The peers' algorithms on the GPU (issue 11): SRP-PHAT and NormMUSIC next to the GEVD.
      { "$C/soundloc" bench --device cuda --algorithm gevd --algorithm srp-phat --batch 256 --repeats 10 --json
        "$C/soundloc" bench --device cuda --algorithm gevd --algorithm sevd --normalize-bins --batch 256 --repeats 10 --json
      } 2>&1 | tee "$OUT/newalg.jsonl" ;;
    allalg)
      "$C/soundloc" bench --device cuda --algorithm sevd --algorithm gevd-hark --batch 256 --repeats 10 --json 2>&1 | tee -a "$OUT/bench.jsonl" ;;
    peer)
      B=${PEER_B:-20} PYTHONUNBUFFERED=1 python3 "$C/peer_torch_gsvd.py" 2>&1 | tee "$OUT/peer.json" ;;
  esac
done
peer="$OUT/peer.json"; [ -s "$peer" ] || peer="$C/peer_last.json"
if [ -s "$OUT/bench.jsonl" ] && [ -s "$peer" ]; then
  { cat "$OUT/bench.jsonl"; cat "$OUT/ab.jsonl" 2>/dev/null; } > "$OUT/all.jsonl"
  python3 - "$OUT/all.jsonl" "$peer" <<'PY'
import json, sys
rows, tag = [], ""
for l in open(sys.argv[1]):
    if l.startswith("== "): tag = l[3:].strip(); continue
    if l.startswith("{"):
        r = json.loads(l); r["tag"] = tag; rows.append(r)
peer = json.load(open(sys.argv[2]))
print("peer figures from", sys.argv[2])
peer_one = peer["torch_gpu_one_window_ms"]; peer_lps = peer["B"] / (peer["torch_gpu_batch_ms"] / 1e3)
gevd_one = peer["torch_gpu_gevd_one_window_ms"]; gevd_lps = peer["B"] / (peer["torch_gpu_gevd_batch_ms"] / 1e3)
print(f"peer GSVD: {peer_one:.1f} ms/loc, {peer_lps:.2f} loc/s; peer GEVD: {gevd_one:.1f} ms/loc, {gevd_lps:.2f} loc/s")
print("alg   prec batch  ms/loc(1)  loc/s(batch)  ms/s@P50  ms/s@P1   corr/dec/spec/peaks ms per loc   x peer(batch)  x peer(1)")
for r in rows:
    c = r["config"]; s = r["stages_per_localization"]; a = c["algorithm"]
    pl, po = (peer_lps, peer_one) if a == "gsvd" else (gevd_lps, gevd_one)
    print(f'{a:5} {r["precision"]} {c["batch"]:5}  {r["ms_per_localization"]:9.3f}  {r["localizations_per_s"]:12.1f}  '
          f'{r["ms_per_audio_s_period50"]:8.3f}  {r["ms_per_audio_s_period1"]:8.2f}   '
          f'{s["correlation_ms"]:.4f}/{s["decomposition_ms"]:.4f}/{s["spectrum_ms"]:.4f}/{s["peaks_ms"]:.4f}   '
          f'{r["localizations_per_s"]/pl:10.0f}  {po/r["ms_per_localization"]:8.0f}  {r["tag"]}')
PY
fi

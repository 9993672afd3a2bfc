#!/usr/bin/env bash
# Coverage-guided fuzzing of every file reader with cargo-afl (see FUZZING.md):
#   scripts/fuzz_afl.sh [LIMIT] [TARGET ...]
# LIMIT per target: N (stop after N executions, afl-fuzz -E), Ns (after N seconds, -V),
# or N:Ms (whichever comes first). Default 1000000:900s. Targets: wav flac tf-zip hgtf
# noise-cm-zip noise-cm-text geometry source-log, and tf-zip@entries noise-cm-zip@entries
# (one zip entry's content, zipped again with valid CRCs); default: all ten.
#
# Installs cargo-afl when missing (it builds AFL++; needs a C compiler and make), builds the
# harness in fuzz/ into target/afl, writes the seed corpora (the valid files soundloc-fuzz
# makes), then runs one afl-fuzz at a time (nice 19, one core) with a 4 GiB memory limit
# (-m 4096) and a 2 s time-out per input (-t 2000). Findings go to target/afl/out/<target>;
# crashing and hanging inputs are also copied to fuzz/crashes/<target>/. Prints per target:
# executions, wall time, corpus size, edge coverage, crashes and hangs (from fuzzer_stats).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
limit="${1:-1000000:900s}"
shift $(( $# > 0 ? 1 : 0 ))
targets=("$@")
((${#targets[@]})) || targets=(wav flac tf-zip tf-zip@entries hgtf noise-cm-zip noise-cm-zip@entries noise-cm-text geometry source-log)

execs=""; secs=""
case "$limit" in
    *:*s) execs="${limit%%:*}"; secs="${limit#*:}"; secs="${secs%s}" ;;
    *s) secs="${limit%s}" ;;
    *) execs="$limit" ;;
esac
stop=()
[ -n "$execs" ] && stop+=(-E "$execs")
[ -n "$secs" ] && stop+=(-V "$secs")

if ! cargo afl --version >/dev/null 2>&1; then
    echo "fuzz_afl.sh: installing cargo-afl" >&2
    command -v cc >/dev/null && command -v make >/dev/null || {
        echo "fuzz_afl.sh: cargo-afl needs a C compiler and make (apt-get install build-essential)" >&2
        exit 2
    }
    nice -n 19 cargo install --locked cargo-afl --version "^0.18"  # matches afl = "0.18" in fuzz/Cargo.toml
fi
# AFL++ itself: built when cargo-afl is installed; this builds it where that did not happen
# (and refuses, harmlessly, where it did).
nice -n 19 cargo afl config --build >/dev/null 2>&1 || true

export CARGO_TARGET_DIR="$root/target/afl"
(cd fuzz && nice -n 19 cargo afl build --release -q)
bin="$CARGO_TARGET_DIR/release/soundloc-afl"
seeds="$CARGO_TARGET_DIR/seeds"
rm -rf "$seeds"
"$bin" --write-seeds "$seeds" >/dev/null

dicts="$(find "${XDG_DATA_HOME:-$HOME/.local/share}/afl.rs" -maxdepth 2 -type d -name dictionaries 2>/dev/null | head -1)"
tmp="$(mktemp -d /dev/shm/soundloc-afl.XXXXXX 2>/dev/null || mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export SOUNDLOC_AFL_TMP="$tmp"
export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1 AFL_NO_AFFINITY=1

summary=()
for t in "${targets[@]}"; do
    [ -d "$seeds/$t" ] || { echo "fuzz_afl.sh: unknown target $t" >&2; exit 2; }
    out="$CARGO_TARGET_DIR/out/$t"
    rm -rf "$out"
    mkdir -p "$out"
    dict=()
    case "$t" in
        wav) d=wav.dict ;;
        geometry) d=toml.dict ;;
        source-log | *@entries) d=xml.dict ;;
        tf-zip | noise-cm-zip) d=zip.dict ;;
        *) d="" ;;
    esac
    [ -n "$d" ] && [ -f "$dicts/$d" ] && dict=(-x "$dicts/$d")
    echo "== $t (${stop[*]}) $(date -u +%H:%M:%S)"
    start=$(date +%s)
    nice -n 19 cargo afl fuzz -i "$seeds/$t" -o "$out" -m 4096 -t 2000 "${stop[@]}" "${dict[@]}" \
        -- "$bin" "$t" >"$out/afl.log" 2>&1 || { echo "afl-fuzz failed for $t:"; tail -30 "$out/afl.log"; exit 1; }
    wall=$(( $(date +%s) - start ))
    stats="$out/default/fuzzer_stats"
    get() { awk -F' *: *' -v k="$1" '$1 == k { print $2 }' "$stats"; }
    crashes=$(get saved_crashes); hangs=$(get saved_hangs)
    for kind in crashes hangs; do
        if compgen -G "$out/default/$kind/id:*" >/dev/null; then
            mkdir -p "fuzz/crashes/$t"
            cp "$out/default/$kind"/id:* "fuzz/crashes/$t/"
        fi
    done
    line=$(printf '%-22s %10s execs %6s s %9s/s corpus %5s edges %5s/%s crashes %3s hangs %3s' \
        "$t" "$(get execs_done)" "$wall" "$(get execs_per_sec)" "$(get corpus_count)" \
        "$(get edges_found)" "$(get total_edges)" "$crashes" "$hangs")
    echo "$line"
    summary+=("$line")
done
echo
echo "== summary (limit $limit, $(date -u +%F))"
printf '%s\n' "${summary[@]}"

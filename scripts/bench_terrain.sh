#!/usr/bin/env bash
# The cost of the terrain columns and of rasters, as CPU-time ratios against a baseline run
# interleaved with them on the same input, so that a machine shared with other work shifts all
# alike.
#
# usage: scripts/bench_terrain.sh [SIZE] [ROUNDS]     (default: 2M points, 9 rounds)
#
# Each round runs, in turn on a warm page cache:
#   base:    tilecurv process IN -o OUT.las -k $K --threads $THREADS --columns H,K,flags
#   terrain: the same with --columns H,K,flags,terrain
#   raster:  the terrain run with --raster 1m (a GeoTIFF and a PNG of each curvature column)
# and prints the CPU time (user + system, /usr/bin/time) of each and the ratios terrain/base
# and raster/terrain; then the median ratios over the rounds, and the ratios of the least CPU
# time of each variant (on a shared virtual machine a run is only ever slowed by its
# neighbours, so the least time is the least disturbed; the two summaries agreeing says the
# rounds were enough), and each variant's median system time (the kernel's part: files and
# page faults). Environment: TILECURV_BENCH_DIR (default /tmp/tilecurv-bench),
# K (30), THREADS (2), SEED (1), TILECURV (a binary; default: cargo build --release).
#
# PAIRED=1 instead runs the two runs of each comparison (base and terrain, then terrain and
# raster) at the same time, one thread each, so that both meet the same neighbours (their
# per-round ratios scattered by 0.06-0.11, as a standard deviation, on this machine; interleaved
# 2-thread rounds by 0.09-0.12), and prints each ratio's median with its standard error. Running at
# once, the two compete for the shared cache and memory, so the ratios include what each
# variant's memory traffic costs the other.
#
# COUNT=1 instead runs each variant once under valgrind's cachegrind and prints the user-space
# instructions each executes and their ratios: repeated runs of 200k points agree within 0.2%
# (the threads' interleaving), so they resolve the 1-2% differences the CPU times of this virtual
# machine cannot (its speed drifts by 20-40% within an hour), but they leave out the kernel's
# work (writing and reading the files, page faults) and what memory stalls cost, which the
# CPU times include. About 40 times as slow as a run: 2M points take about 6 minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH_DIR=${TILECURV_BENCH_DIR:-/tmp/tilecurv-bench}
SIZE=${1:-2M}
ROUNDS=${2:-9}
K=${K:-30}
THREADS=${THREADS:-2}
SEED=${SEED:-1}
command -v /usr/bin/time >/dev/null || { echo "bench_terrain.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
if [ -z "${TILECURV:-}" ]; then
    cargo build --release --locked --quiet
    TILECURV=${CARGO_TARGET_DIR:-$PWD/target}/release/tilecurv
fi
mkdir -p "$BENCH_DIR"
in="$BENCH_DIR/terrain_${SIZE}_seed${SEED}.las"
[ -f "$in" ] || "$TILECURV" generate terrain -q -o "$in" --points "$SIZE" --seed "$SEED"
cpu_s() { awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.2f", s }' "$1"; }
sys_s() { awk -F': ' '/System time/ { printf "%.2f", $2 }' "$1"; }
# The median of the numbers given (of an even count, the lower of the two middle ones).
med() { printf '%s\n' "$@" | sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
declare -A variants=(
    [base]="--columns H,K,flags"
    [terrain]="--columns H,K,flags,terrain"
    [raster]="--columns H,K,flags,terrain --raster 1m"
)
order=(base terrain raster)
if [ "${COUNT:-0}" = 1 ]; then
    command -v valgrind >/dev/null || { echo "bench_terrain.sh: COUNT=1 needs valgrind (apt-get install valgrind)" >&2; exit 2; }
    declare -A ins=()
    for v in "${order[@]}"; do
        out="$BENCH_DIR/bench_terrain_$v.las"
        # shellcheck disable=SC2086
        ins[$v]=$(valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
            "$TILECURV" process "$in" -o "$out" -q -k "$K" --threads "$THREADS" ${variants[$v]} 2>&1 |
            sed -n 's/.*I *refs: *//p' | tr -d ',')
        rm -rf "$out" "${out%.las}.rasters"
        printf '%-8s %16s instructions\n' "$v" "${ins[$v]}"
    done
    awk -v b="${ins[base]}" -v t="${ins[terrain]}" -v r="${ins[raster]}" 'BEGIN {
        printf "input: %s points; instruction ratios terrain/base %.4f, raster/terrain %.4f\n", "'"$SIZE"'", t / b, r / t }'
    exit 0
fi
if [ "${PAIRED:-0}" = 1 ]; then
    declare -A paired=()
    printf '%-6s %10s %12s %12s %11s %8s %8s\n' round "base (s)" "terrain (s)" "terrain (s)" \
        "raster (s)" terrain raster
    for r in $(seq 1 "$ROUNDS"); do
        line=()
        shown_ratios=()
        for pair in "base terrain" "terrain raster"; do
            read -r a b <<<"$pair"
            cat "$in" >/dev/null
            pids=()
            for v in "$a" "$b"; do
                out="$BENCH_DIR/bench_terrain_paired_$v.las"
                # shellcheck disable=SC2086
                /usr/bin/time -v -o "$BENCH_DIR/time_paired_$v.txt" "$TILECURV" process "$in" \
                    -o "$out" -q -k "$K" --threads 1 ${variants[$v]} &
                pids+=("$!")
            done
            # Each run waited for by itself, so that a failed one stops the script.
            for p in "${pids[@]}"; do
                wait "$p" || {
                    echo "bench_terrain.sh: a run of the pair '$pair' failed (its report: $BENCH_DIR/time_paired_*.txt)" >&2
                    exit 1
                }
            done
            ca=$(cpu_s "$BENCH_DIR/time_paired_$a.txt")
            cb=$(cpu_s "$BENCH_DIR/time_paired_$b.txt")
            # The ratio once: to four places for the summary, to three for the round's line.
            read -r exact shown < <(awk -v a="$ca" -v b="$cb" 'BEGIN { printf "%.4f %.3f\n", b / a, b / a }')
            paired[$b]="${paired[$b]:-} $exact"
            line+=("$ca" "$cb")
            shown_ratios+=("$shown")
            rm -rf "$BENCH_DIR"/bench_terrain_paired_*
        done
        printf '%-6s %10s %12s %12s %11s %8s %8s\n' "$r" "${line[@]}" "${shown_ratios[@]}"
    done
    # Median, mean and standard deviation of a variant's ratios, and the median's standard
    # error (1.2533 sd / sqrt(n) for ratios scattered about normally).
    summary() {
        # shellcheck disable=SC2086
        printf '%s\n' $1 | awk -v med="$(med $1)" '{ s += $1; q += $1 * $1 } END {
            m = s / NR; var = NR > 1 ? (q - NR * m * m) / (NR - 1) : 0; sd = sqrt(var > 0 ? var : 0)
            printf "median %.3f (standard error %.3f), mean %.3f, standard deviation %.3f", med, 1.2533 * sd / sqrt(NR), m, sd }'
    }
    echo "input: $in ($SIZE points), -k $K, pairs at once with --threads 1, $ROUNDS rounds:"
    echo "  terrain/base:   $(summary "${paired[terrain]}")"
    echo "  raster/terrain: $(summary "${paired[raster]}")"
    exit 0
fi
ratios=()
raster_ratios=()
declare -A least=() sys_times=()
printf '%-6s %10s %12s %11s %8s %8s\n' round "base (s)" "terrain (s)" "raster (s)" terrain raster
for r in $(seq 1 "$ROUNDS"); do
    declare -A cpu=()
    for v in "${order[@]}"; do
        cat "$in" >/dev/null
        out="$BENCH_DIR/bench_terrain_$v.las"
        # shellcheck disable=SC2086
        /usr/bin/time -v -o "$BENCH_DIR/time_$v.txt" "$TILECURV" process "$in" -o "$out" -q \
            -k "$K" --threads "$THREADS" ${variants[$v]}
        cpu[$v]=$(cpu_s "$BENCH_DIR/time_$v.txt")
        sys_times[$v]="${sys_times[$v]:-} $(sys_s "$BENCH_DIR/time_$v.txt")"
        least[$v]=$(awk -v a="${cpu[$v]}" -v b="${least[$v]:-}" 'BEGIN { print (b == "" || a < b) ? a : b }')
        rm -rf "$out" "${out%.las}.rasters"
    done
    ratio=$(awk -v a="${cpu[terrain]}" -v b="${cpu[base]}" 'BEGIN { printf "%.3f", a / b }')
    rratio=$(awk -v a="${cpu[raster]}" -v b="${cpu[terrain]}" 'BEGIN { printf "%.3f", a / b }')
    ratios+=("$ratio")
    raster_ratios+=("$rratio")
    printf '%-6s %10s %12s %11s %8s %8s\n' "$r" "${cpu[base]}" "${cpu[terrain]}" "${cpu[raster]}" "$ratio" "$rratio"
done
echo "input: $in ($SIZE points), -k $K, --threads $THREADS; median CPU ratios over $ROUNDS rounds: terrain/base $(med "${ratios[@]}"), raster/terrain $(med "${raster_ratios[@]}")"
awk -v b="${least[base]}" -v t="${least[terrain]}" -v r="${least[raster]}" 'BEGIN {
    printf "least CPU time: base %.2f s, terrain %.2f s, raster %.2f s; ratios terrain/base %.3f, raster/terrain %.3f\n", b, t, r, t / b, r / t }'
# The kernel's part of the CPU time (writing and reading files, page faults), which the
# instruction counts of COUNT=1 leave out.
# shellcheck disable=SC2086
echo "median system time: base $(med ${sys_times[base]}) s, terrain $(med ${sys_times[terrain]}) s, raster $(med ${sys_times[raster]}) s"

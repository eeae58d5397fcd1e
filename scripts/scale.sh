#!/usr/bin/env bash
# Scaling run: generated terrains of 1M, 10M and 100M points through `tilecurv process` (or the
# cluster stages one after the other) with a fixed memory budget; prints time, CPU time, peak
# RSS and the peak disk of the work directory in bytes a point: all of it, and its buckets/ and
# results/ apart (each their own peak), sampled with `du -sb` every 0.5 s; then the time of each
# phase (scan, curvature, write: the phase_end events of --progress-json). Peak RSS should stay
# flat (about the budget plus ~60 MiB) while the points grow a hundredfold; the work directory
# peaks once the tiles are done (the buckets, if they spilled, plus the result files: about 5 +
# 7 bytes a point on the terrain with the default columns, 5 + 19 with normals, k1, k2), or while assemble merges more result files than it may
# open at once (run files, up to as much again as the results), and is gone at the end.
#
# usage: scripts/scale.sh [SIZE...]        (default: 1M 10M 100M; sizes as `generate --points`;
#        the rates are also given as ratios to the first size's, and a size listed several
#        times by its median: `20M 100M 300M 20M 100M 300M` interleaves two rounds)
#
# Environment: TILECURV_SCALE_DIR (inputs, outputs and work directories; default
# /tmp/tilecurv-scale; 100M points need about 6 GB of input, 9 GB of output and a few GB of
# work directory), MEMORY (default 2G; 512M makes the buckets of 10M points spill), THREADS
# (default: all cores), FORMAT (las or laz, default las), SEED (default 1), STAGES (process, the
# default, or split: plan, bucket, run-tile and assemble as separate commands, whose buckets
# always go to disk), TILECURV (the binary; default: built here with cargo build --release, in
# CARGO_TARGET_DIR if set), KEEP_OUTPUTS=1 to keep the outputs, TRUTH=none for inputs without
# the generator's truth columns (28 instead of 60 bytes a record: `generate --no-truth`),
# MEMORY=default to run without --memory (the default budget), POLL (seconds between two
# samples of the work directory's size, default 0.5, and at least 50 times as long as the
# last walk took: du walks every file). Inputs are cached. Compare two
# binaries with the same script, input and settings: TILECURV=old/tilecurv scripts/scale.sh 2M.
set -euo pipefail
cd "$(dirname "$0")/.."

DIR=${TILECURV_SCALE_DIR:-/tmp/tilecurv-scale}
MEMORY=${MEMORY:-2G}
TRUTH=${TRUTH:-curvature}
POLL=${POLL:-0.5}
MEMORY_ARGS=(--memory "$MEMORY")
[ "$MEMORY" != default ] || MEMORY_ARGS=()
TRUTH_ARGS=()
[ "$TRUTH" != none ] || TRUTH_ARGS=(--no-truth)
FORMAT=${FORMAT:-las}
SEED=${SEED:-1}
STAGES=${STAGES:-process}
SIZES=("$@")
[ ${#SIZES[@]} -gt 0 ] || SIZES=(1M 10M 100M)
THREAD_ARGS=()
[ -z "${THREADS:-}" ] || THREAD_ARGS=(--threads "$THREADS")

command -v /usr/bin/time >/dev/null || { echo "scale.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
mkdir -p "$DIR"
if [ -z "${TILECURV:-}" ]; then
    cargo build --release --locked --quiet
    TILECURV=${CARGO_TARGET_DIR:-$PWD/target}/release/tilecurv
fi
BIN=$TILECURV

# Runs "$@" under /usr/bin/time, appending "wall cpu rss_kib" to $1's time file.
timed() {
    local file=$1
    shift
    /usr/bin/time -f '%e %U %S %M' -a -o "$file" "$@"
}

# The work directory's stages as `process` or as the cluster commands, all timed into $1, their
# phase events appended to $5.
run_stages() {
    local tfile=$1 in=$2 out=$3 work=$4 prog=$5
    local common=("${MEMORY_ARGS[@]}" "${THREAD_ARGS[@]}" -q --progress-json "$prog")
    if [ "$STAGES" = split ]; then
        timed "$tfile" "$BIN" plan "$in" --work "$work" --tiles-per-task 1000000 -q >/dev/null
        timed "$tfile" "$BIN" bucket --work "$work" "${common[@]}"
        timed "$tfile" "$BIN" run-tile --work "$work" --task 0 "${common[@]}"
        timed "$tfile" "$BIN" assemble --work "$work" -o "$out" "${common[@]}"
        rm -rf "$work" # the cluster stages keep it
    else
        timed "$tfile" "$BIN" process "$in" -o "$out" --work-dir "$work" "${common[@]}"
    fi
}

# "scan 0.9 s, curvature 13.2 s, write 1.3 s" from the phase_end events of a progress file.
phases() {
    sed -n 's/.*"event":"phase_end","phase":"\([a-z]*\)".*"elapsed_s":\([0-9.]*\).*/\1 \2 s/p' "$1" |
        paste -sd, - | sed 's/,/, /g'
}

summary="$DIR/summary.txt"
printf '%-6s %11s %9s %9s %9s %11s %11s %11s %10s %8s\n' size points "wall (s)" "CPU (s)" "RSS (MiB)" \
    "work B/pt" "buckets" "results" "points/s" "x first" >"$summary"
first_rate=""
declare -A rates=()
order=()
for size in "${SIZES[@]}"; do
    in="$DIR/terrain_${size}_seed${SEED}_truth-${TRUTH}.$FORMAT"
    if [ ! -f "$in" ]; then
        "$BIN" generate terrain -o "$in" --points "$size" --seed "$SEED" -q "${TRUTH_ARGS[@]}"
    fi
    out="$DIR/out_$size.$FORMAT"
    work="$DIR/work_$size"
    rm -rf "$out" "$work"
    # Every run starts from a warm page cache (as bench_pgeof.sh's): on this project's virtual
    # machine the first touch of a cached file's pages after other work can cost ~2 us of CPU a
    # page (a 6 GB file: 12 s of user time in a plain mmap reader, 0.4 s the next time), which
    # would be counted as the scan's.
    cat "$in" >/dev/null

    # Peak disk of the work directory and of its two folders: poll du in the background.
    peak_file="$DIR/du_peak_$size.txt"
    echo "0 0 0" >"$peak_file"
    (
        peak=(0 0 0)
        while true; do
            # One walk of the tree a sample (du -d1: the total and each folder's): at 100M
            # points the work directory holds ~8,000 files, and three walks every 0.5 s took
            # a few percent of the run's CPU.
            started=$(date +%s%N)
            sizes=$(du -b -d1 "$work" 2>/dev/null || true)
            i=0
            for d in "$work" "$work/buckets" "$work/results"; do
                b=$(printf '%s\n' "$sizes" | awk -F'\t' -v d="$d" '$2 == d { print $1 }')
                if [ -n "$b" ] && [ "$b" -gt "${peak[$i]}" ]; then peak[i]=$b; fi
                i=$((i + 1))
            done
            echo "${peak[*]}" >"$peak_file"
            # At least 50 times as long as the walk took: du's own CPU stays under 2% of a
            # core however many files the work directory holds (24,000 at 300M points).
            took=$(($(date +%s%N) - started))
            sleep "$(awk -v p="$POLL" -v t="$took" 'BEGIN { s = 50 * t / 1e9; print (s > p ? s : p) }')"
        done
    ) &
    poller=$!

    time_file="$DIR/time_$size.txt"
    : >"$time_file"
    # --progress-json appends: a previous run's events would be read as this run's phases.
    prog_file="$DIR/progress_$size.jsonl"
    rm -f "$prog_file"
    status=0
    run_stages "$time_file" "$in" "$out" "$work" "$prog_file" || status=$?
    kill "$poller" 2>/dev/null || true
    wait "$poller" 2>/dev/null || true
    if [ "$status" -ne 0 ]; then
        echo "scale.sh: tilecurv failed on $in (exit $status); see $time_file" >&2
        exit "$status"
    fi

    # The point count of the generated header (the legacy u32 at byte 107).
    points=$(od -An -t u4 -j 107 -N 4 "$in" | tr -d ' ')
    # The rate end to end, and its ratio to the first size's rate in this script (a size listed
    # twice, first and last, shows how far the machine drifted meanwhile).
    wall=$(awk '{ w += $1 } END { print w }' "$time_file")
    rate=$(awk -v n="$points" -v w="$wall" 'BEGIN { print n / w }')
    [ -n "$first_rate" ] || first_rate=$rate
    rates[$size]="${rates[$size]:-} $rate"
    [[ " ${order[*]} " == *" $size "* ]] || order+=("$size")
    awk -v size="$size" -v n="$points" -v peaks="$(cat "$peak_file")" -v first="$first_rate" '
        { wall += $1; cpu += $2 + $3; if ($4 > rss) rss = $4 }
        END {
            split(peaks, p, " ")
            printf "%-6s %11d %9.1f %9.1f %9.0f %11.2f %11.2f %11.2f %10.0f %8.3f\n", size, n, wall,
                cpu, rss / 1024, p[1] / n, p[2] / n, p[3] / n, n / wall, n / wall / first
        }' "$time_file" >>"$summary"
    echo "       phases: $(phases "$prog_file")" >>"$summary"
    echo "       input $(stat -c %s "$in") bytes, output $(stat -c %s "$out") bytes" >>"$summary"
    [ "${KEEP_OUTPUTS:-0}" = 1 ] || rm -f "$out"
    [ ! -e "$work" ] || echo "scale.sh: warning: the work directory $work was left behind" >&2
done
# A size listed several times (interleaved with the others: `20M 100M 20M 100M`) is summed up
# by its median rate, and each median as a ratio to the first size's: the machine's drift
# then weighs on every size alike.
median() { tr ' ' '\n' | sed '/^$/d' | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
base_median=$(echo "${rates[${order[0]}]}" | median)
for size in "${order[@]}"; do
    m=$(echo "${rates[$size]}" | median)
    awk -v size="$size" -v runs="$(echo "${rates[$size]}" | wc -w)" -v m="$m" -v b="$base_median" \
        'BEGIN { printf "median %-6s %d run(s): %.0f points/s, %.3f x %s\n", size, runs, m, m / b, "'"${order[0]}"'" }' >>"$summary"
done
echo "$BIN: $STAGES, --memory $MEMORY, $(nproc) cores${THREADS:+, --threads $THREADS}, $FORMAT input, truth columns: $TRUTH"
cat "$summary"

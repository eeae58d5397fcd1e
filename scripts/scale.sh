#!/usr/bin/env bash
# Scaling run: generated terrains of 1M, 10M and 100M points through `tilecurv process` with a
# fixed memory budget; prints time, points/s, peak RSS and the peak disk used by the work
# directory for each size. Peak RSS should stay flat (about the budget plus ~60 MiB) while the
# points grow a hundredfold; the work directory should peak at roughly the bucket spill plus
# the result files (about 45 + 37 bytes per point) and be gone at the end.
#
# usage: scripts/scale.sh [SIZE...]        (default: 1M 10M 100M; sizes as `generate --points`)
#
# Environment: TILECURV_SCALE_DIR (inputs, outputs and work directories; default
# /tmp/tilecurv-scale; 100M points need about 6 GB of input, 9 GB of output and a few GB of
# work directory), MEMORY (default 2G), THREADS (default: all cores), FORMAT (las or laz,
# default las), SEED (default 1), KEEP_OUTPUTS=1 to keep the outputs. Inputs are cached.
set -euo pipefail
cd "$(dirname "$0")/.."

DIR=${TILECURV_SCALE_DIR:-/tmp/tilecurv-scale}
MEMORY=${MEMORY:-2G}
FORMAT=${FORMAT:-las}
SEED=${SEED:-1}
SIZES=("$@")
[ ${#SIZES[@]} -gt 0 ] || SIZES=(1M 10M 100M)
THREAD_ARGS=()
[ -z "${THREADS:-}" ] || THREAD_ARGS=(--threads "$THREADS")

command -v /usr/bin/time >/dev/null || { echo "scale.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
mkdir -p "$DIR"
cargo build --release --locked --quiet
BIN=$PWD/target/release/tilecurv

summary="$DIR/summary.txt"
printf '%-6s %12s %10s %12s %10s %14s\n' size points "time (s)" "points/s" "RSS (MiB)" "work disk (MiB)" >"$summary"
for size in "${SIZES[@]}"; do
    in="$DIR/terrain_${size}_seed${SEED}.$FORMAT"
    if [ ! -f "$in" ]; then
        "$BIN" generate terrain -o "$in" --points "$size" --seed "$SEED"
    fi
    out="$DIR/out_$size.$FORMAT"
    work="$DIR/work_$size"
    rm -rf "$out" "$work"

    # Peak disk of the work directory: poll du in the background while the run lasts.
    peak_file="$DIR/du_peak_$size.txt"
    echo 0 >"$peak_file"
    (
        peak=0
        while true; do
            b=$(du -sb "$work" 2>/dev/null | cut -f1 || true)
            if [ -n "$b" ] && [ "$b" -gt "$peak" ]; then
                peak=$b
                echo "$peak" >"$peak_file"
            fi
            sleep 1
        done
    ) &
    poller=$!

    time_file="$DIR/time_$size.txt"
    status=0
    /usr/bin/time -v -o "$time_file" "$BIN" process "$in" -o "$out" --memory "$MEMORY" \
        --work-dir "$work" "${THREAD_ARGS[@]}" || status=$?
    kill "$poller" 2>/dev/null || true
    wait "$poller" 2>/dev/null || true
    if [ "$status" -ne 0 ]; then
        echo "scale.sh: tilecurv failed on $in (exit $status); see $time_file" >&2
        exit "$status"
    fi

    # The point count of the generated LAS 1.2 header (u32 at byte 107).
    points=$(od -An -t u4 -j 107 -N 4 "$in" | tr -d ' ')
    secs=$(awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i]; print s }' "$time_file")
    rss=$(awk -F': ' '/Maximum resident set size/ { printf "%.0f", $2 / 1024 }' "$time_file")
    disk=$(awk '{ printf "%.0f", $1 / 1048576 }' "$peak_file")
    awk -v size="$size" -v n="$points" -v t="$secs" -v rss="$rss" -v disk="$disk" 'BEGIN {
        printf "%-6s %12d %10.1f %12.0f %10d %14d\n", size, n, t, n / t, rss, disk
    }' >>"$summary"
    [ "${KEEP_OUTPUTS:-0}" = 1 ] || rm -f "$out"
    [ ! -e "$work" ] || echo "scale.sh: warning: the work directory $work was left behind" >&2
done
echo "--memory $MEMORY, $(nproc) cores${THREADS:+, --threads $THREADS}, $FORMAT input"
cat "$summary"

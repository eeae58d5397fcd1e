#!/usr/bin/env bash
# tilecurv against pgeof, end to end on the same generated terrain (file in, file out).
#
# usage: scripts/bench_pgeof.sh [SIZE...]      (default: 2M 20M; sizes as `generate --points`)
#
# For each size: generates a LAS terrain with `tilecurv generate terrain` (cached under
# $TILECURV_BENCH_DIR, default /tmp/tilecurv-bench), then times
#   tilecurv process IN -o OUT.las -k $K --threads $THREADS          (release build)
#   python3 scripts/bench_pgeof.py IN OUT.las $K                      (laspy read, pgeof.knn_search
#                                                                      + compute_features on all
#                                                                      cores, laspy write)
# with /usr/bin/time -v, and prints points/s of each, their ratio, and the peak RSS of each;
# tilecurv's time per phase (scan, curvature, write: the phase_end events of --progress-json)
# and its CPU time; then tilecurv again with --threads 1 for the thread scaling (SCALING=0
# skips it). pgeof, laspy and numpy are installed into a virtual environment under the bench
# directory (a system Python may refuse pip installs).
# The input is read once before each run so that all start from a warm page cache.
#
# Environment: TILECURV_BENCH_DIR (cache and outputs), K (default 30), THREADS (tilecurv
# threads, default 2), SEED (terrain seed, default 1), KEEP_OUTPUTS=1 to keep the outputs,
# SCALING=0 to skip the one-thread run.
# The two tools do not compute the same thing: tilecurv writes H, K and flags by default (CNC
# estimator); pgeof writes PCA eigenvalue features and a normal. Both do a k-NN search and a
# per-point PCA over K neighbours, which dominate pgeof's time.
set -euo pipefail
cd "$(dirname "$0")/.."

BENCH_DIR=${TILECURV_BENCH_DIR:-/tmp/tilecurv-bench}
K=${K:-30}
THREADS=${THREADS:-2}
SEED=${SEED:-1}
SIZES=("$@")
[ ${#SIZES[@]} -gt 0 ] || SIZES=(2M 20M)

command -v /usr/bin/time >/dev/null || { echo "bench_pgeof.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
mkdir -p "$BENCH_DIR"
VENV=$BENCH_DIR/venv
[ -x "$VENV/bin/python3" ] || python3 -m venv "$VENV"
"$VENV/bin/python3" -m pip install --quiet --disable-pip-version-check \
    'pgeof==0.3.4' 'laspy[lazrs]==2.7.0' 'numpy<3'
if [ -z "${TILECURV:-}" ]; then
    cargo build --release --locked --quiet
    TILECURV=${CARGO_TARGET_DIR:-$PWD/target}/release/tilecurv
fi
BIN=$TILECURV

# seconds, CPU seconds and peak RSS (MiB) from a /usr/bin/time -v report
wall_s() { awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i]; print s }' "$1"; }
cpu_s() { awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.1f", s }' "$1"; }
# "scan 2.9 s, curvature 24.8 s, write 7.4 s" from the phase_end events of --progress-json
phases() { sed -n 's/.*"event":"phase_end","phase":"\([a-z]*\)".*"elapsed_s":\([0-9.]*\).*/\1 \2 s/p' "$1" | paste -sd, - | sed 's/,/, /g'; }
rss_mib() { awk -F': ' '/Maximum resident set size/ { printf "%.0f", $2 / 1024 }' "$1"; }

printf '\n%-6s %-9s %10s %12s %10s\n' size tool "time (s)" "points/s" "RSS (MiB)" >"$BENCH_DIR/summary.txt"
for size in "${SIZES[@]}"; do
    in="$BENCH_DIR/terrain_${size}_seed${SEED}.las"
    if [ ! -f "$in" ]; then
        "$BIN" generate terrain -o "$in" --points "$size" --seed "$SEED"
    fi
    points=$(od -An -t u4 -j 107 -N 4 "$in" | tr -d ' ') # LAS 1.2 point count

    cat "$in" >/dev/null
    out_tc="$BENCH_DIR/out_tilecurv_$size.las"
    # --progress-json appends: a previous run's events would be read as this run's phases.
    rm -f "$out_tc" "$BENCH_DIR/progress_tilecurv_$size.jsonl"
    /usr/bin/time -v -o "$BENCH_DIR/time_tilecurv_$size.txt" \
        "$BIN" process "$in" -o "$out_tc" -k "$K" --threads "$THREADS" -q \
        --progress-json "$BENCH_DIR/progress_tilecurv_$size.jsonl"
    t_tc=$(wall_s "$BENCH_DIR/time_tilecurv_$size.txt")
    c_tc=$(cpu_s "$BENCH_DIR/time_tilecurv_$size.txt")
    p_tc=$(phases "$BENCH_DIR/progress_tilecurv_$size.jsonl")
    m_tc=$(rss_mib "$BENCH_DIR/time_tilecurv_$size.txt")

    cat "$in" >/dev/null
    out_pg="$BENCH_DIR/out_pgeof_$size.las"
    rm -f "$out_pg"
    /usr/bin/time -v -o "$BENCH_DIR/time_pgeof_$size.txt" \
        "$VENV/bin/python3" scripts/bench_pgeof.py "$in" "$out_pg" "$K"
    t_pg=$(wall_s "$BENCH_DIR/time_pgeof_$size.txt")
    c_pg=$(cpu_s "$BENCH_DIR/time_pgeof_$size.txt")
    m_pg=$(rss_mib "$BENCH_DIR/time_pgeof_$size.txt")

    t_tc1=0
    if [ "${SCALING:-1}" != 0 ]; then
        cat "$in" >/dev/null
        rm -f "$out_tc"
        /usr/bin/time -v -o "$BENCH_DIR/time_tilecurv1_$size.txt" \
            "$BIN" process "$in" -o "$out_tc" -k "$K" --threads 1 -q
        t_tc1=$(wall_s "$BENCH_DIR/time_tilecurv1_$size.txt")
    fi

    [ "${KEEP_OUTPUTS:-0}" = 1 ] || rm -f "$out_tc" "$out_pg"
    awk -v size="$size" -v n="$points" -v ttc="$t_tc" -v tpg="$t_pg" -v mtc="$m_tc" -v mpg="$m_pg" \
        -v ttc1="$t_tc1" -v threads="$THREADS" -v cores="$(nproc)" -v ctc="$c_tc" -v cpg="$c_pg" \
        -v phases="$p_tc" 'BEGIN {
        printf "%-6s %-9s %10.1f %12.0f %10d   (--threads %d; CPU %.1f s; %s)\n", size, "tilecurv", ttc, n / ttc, mtc, threads, ctc, phases
        printf "%-6s %-9s %10.1f %12.0f %10d   (all %d cores; CPU %.1f s)\n", size, "pgeof", tpg, n / tpg, mpg, cores, cpg
        printf "%-6s ratio tilecurv/pgeof points/s: %.2f; RSS: %.2f\n", size, tpg / ttc, mtc / mpg
        if (ttc1 > 0)
            printf "%-6s tilecurv --threads 1: %.1f s, %.0f points/s; speed-up at %d threads: %.2f\n", size, ttc1, n / ttc1, threads, ttc1 / ttc
    }' >>"$BENCH_DIR/summary.txt"
done
cat "$BENCH_DIR/summary.txt"

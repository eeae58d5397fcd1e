#!/usr/bin/env bash
# CPU and wall time of two tilecurv binaries on the same input, interleaved (A B A B ...), so
# that drift of the machine (other load, CPU frequency, page cache) falls on both alike. For
# refactors that must not cost time: their CPU ratio should be 1 within the rounds' scatter.
#
# usage: scripts/compare_cpu.sh BASE_BIN NEW_BIN [SIZE] [ROUNDS]
#
#   BASE_BIN, NEW_BIN  two tilecurv binaries (e.g. target-cmp-base/release/tilecurv, the one
#                      scripts/compare_commits.sh builds, and target/release/tilecurv)
#   SIZE               terrain points, as `generate --points` (default 20M)
#   ROUNDS             pairs of runs (default 3)
#
# Each run is `process IN -o OUT.las` at default settings (2 threads unless THREADS is set),
# from a warm page cache (the input is read before each run). Prints one line per run and the
# medians' ratio NEW / BASE of CPU and wall time; checks that the outputs are byte-identical.
# Environment: TILECURV_BENCH_DIR (default /tmp/tilecurv-bench, shared with bench_pgeof.sh),
# THREADS (default 2), SEED (terrain seed, default 1).
set -euo pipefail
[ $# -ge 2 ] && [ $# -le 4 ] || { sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2; exit 2; }
BASE=$1
NEW=$2
SIZE=${3:-20M}
ROUNDS=${4:-3}
DIR=${TILECURV_BENCH_DIR:-/tmp/tilecurv-bench}
THREADS=${THREADS:-2}
SEED=${SEED:-1}
command -v /usr/bin/time >/dev/null || { echo "compare_cpu.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
mkdir -p "$DIR"
in=$DIR/terrain_${SIZE}_seed${SEED}.las
[ -f "$in" ] || "$NEW" generate terrain -o "$in" --points "$SIZE" --seed "$SEED"

cpu_s() { awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.2f", s }' "$1"; }
wall_s() { awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i]; print s }' "$1"; }
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

declare -A cpus walls
for r in $(seq 1 "$ROUNDS"); do
    for which in base new; do
        bin=$BASE
        [ "$which" = new ] && bin=$NEW
        out=$DIR/cmp_$which.las
        cat "$in" >/dev/null
        /usr/bin/time -v "$bin" process "$in" -o "$out" --threads "$THREADS" -q 2>"$DIR/cmp_time.txt"
        c=$(cpu_s "$DIR/cmp_time.txt")
        w=$(wall_s "$DIR/cmp_time.txt")
        cpus[$which]+="$c "
        walls[$which]+="$w "
        printf 'round %d %-4s cpu %7.2f s  wall %7.2f s\n' "$r" "$which" "$c" "$w"
    done
    cmp -s "$DIR/cmp_base.las" "$DIR/cmp_new.las" || { echo "compare_cpu.sh: the outputs differ (round $r)" >&2; exit 1; }
done
bc_=$(echo "${cpus[base]}" | tr ' ' '\n' | grep . | median)
nc_=$(echo "${cpus[new]}" | tr ' ' '\n' | grep . | median)
bw_=$(echo "${walls[base]}" | tr ' ' '\n' | grep . | median)
nw_=$(echo "${walls[new]}" | tr ' ' '\n' | grep . | median)
awk -v bc="$bc_" -v nc="$nc_" -v bw="$bw_" -v nw="$nw_" -v size="$SIZE" 'BEGIN {
    printf "%s points, medians: cpu base %.2f s new %.2f s (ratio %.3f); wall base %.2f s new %.2f s (ratio %.3f); outputs identical\n", size, bc, nc, nc / bc, bw, nw, nw / bw
}'
rm -f "$DIR/cmp_base.las" "$DIR/cmp_new.las" "$DIR/cmp_time.txt"

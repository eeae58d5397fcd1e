#!/usr/bin/env bash
# A billion points on one machine, measured: generates a 1e9-point LAZ terrain (point format 1
# without the generator's truth columns, about 5 bytes a point), runs `tilecurv process` on it
# to LAZ at default settings (no --memory: the default budget; every core), and prints wall
# time, CPU time, peak RSS, the work directory's peak in bytes a point (all of it, buckets/ and
# results/), the input and output sizes and the time of each phase. It is scripts/scale.sh with
# these settings; set POINTS for another size (e.g. POINTS=100M for a rehearsal).
#
# usage: scripts/billion.sh
#
# Needs about 33 bytes a point of free disk in TILECURV_SCALE_DIR (default /tmp/tilecurv-scale):
# 4 of input, 6 of LAZ output and 11.5 of work directory at its peak as measured (README), the
# rest a margin for the other columns' larger outputs and results; refused (exit 2) when the disk
# has less. Environment: TILECURV (a binary), TILECURV_SCALE_DIR, POINTS (default 1000M).
set -euo pipefail
cd "$(dirname "$0")/.."
DIR=${TILECURV_SCALE_DIR:-/tmp/tilecurv-scale}
POINTS=${POINTS:-1000M}
mkdir -p "$DIR"
n=$(awk -v s="$POINTS" 'BEGIN { m = 1; if (s ~ /M$/) m = 1e6; if (s ~ /G$/) m = 1e9; if (s ~ /k$/) m = 1e3; sub(/[kMG]$/, "", s); printf "%.0f", s * m }')
need=$((n * 33))
free=$(df -B1 --output=avail "$DIR" | tail -1 | tr -d ' ')
if [ "$free" -lt "$need" ]; then
    echo "billion.sh: $DIR has $((free >> 30)) GiB free; $POINTS points need about $((need >> 30)) GiB (33 bytes a point): free space or set TILECURV_SCALE_DIR" >&2
    exit 2
fi
echo "billion.sh: $POINTS points, $((free >> 30)) GiB free in $DIR, about $((need >> 30)) GiB needed"
FORMAT=laz TRUTH=none MEMORY=default POLL=5 exec bash scripts/scale.sh "$POINTS"

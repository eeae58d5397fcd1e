#!/usr/bin/env bash
# The estimator study (docs/study.md): runs the single-threaded driver
# benches/study.rs, which writes one CSV row per (cloud, K, estimator), then draws the SVG plots
# and the Markdown tables with scripts/study_plots.py.
#
#   bash scripts/study.sh            full protocol (~20 min on 2 cores) -> docs/study/
#   bash scripts/study.sh --quick    N = 10k, diagonal noise only (< 2 min) -> target/study-quick/
#   bash scripts/study.sh --out DIR  write somewhere else
# Other arguments go to the driver (--subset N, --only a,b).
set -euo pipefail
cd "$(dirname "$0")/.."

quick=0
out=""
args=()
while [ $# -gt 0 ]; do
    case "$1" in
        --quick) quick=1; args+=(--quick) ;;
        --out) out="$2"; shift ;;
        *) args+=("$1") ;;
    esac
    shift
done
if [ -z "$out" ]; then
    if [ "$quick" = 1 ]; then out=target/study-quick; else out=docs/study; fi
fi
mkdir -p "$out"

cargo bench --bench study --no-run --quiet
{
    echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n1)"
    echo "cores: $(nproc)"
    echo "threads: 1 (the driver is single-threaded)"
    echo "rustc: $(rustc --version)"
    echo "mode: $([ "$quick" = 1 ] && echo quick || echo full)"
    echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
} > "$out/machine.txt"
start=$(date +%s)
cargo bench --bench study --quiet -- --csv "$out/results.csv" "${args[@]}"
{
    echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "wall time: $(( $(date +%s) - start )) s"
} >> "$out/machine.txt"
python3 scripts/study_plots.py "$out"
echo "study: results, plots and tables in $out"

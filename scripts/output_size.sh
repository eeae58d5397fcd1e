#!/usr/bin/env bash
# Size of a LAZ output against its LAZ input: runs `tilecurv process` on the
# shipped sample (data/Haystack_Rock.las, converted to LAZ with laspy + lazrs first, since it
# ships as LAS) and on the shared bcts_1.laz, bcts_2.laz and autzen_trim.laz, once per option
# set, and prints a Markdown table: input bytes, output bytes, output / input.
#
# usage: bash scripts/output_size.sh [OPTIONS ...]
#
#   OPTIONS   option sets to compare, each one quoted argument (default: "" "--f32", i.e. the
#             default scaled-integer columns against 32-bit floats), e.g.
#             bash scripts/output_size.sh "" "--f32" "--columns H,K,flags"
#
# Environment:
#   TILECURV   the binary (default: target/release/tilecurv, built with cargo build --release)
#   PYTHON     a python3 with laspy and lazrs (default: python3)
#   DATA_DIR   the shared inputs (default: ../shared/data beside the repository)
set -euo pipefail

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DATA=${DATA_DIR:-$REPO/../shared/data}
PYTHON=${PYTHON:-python3}
if [ -z "${TILECURV:-}" ]; then
    (cd "$REPO" && cargo build --release --locked -q)
    TILECURV=${CARGO_TARGET_DIR:-$REPO/target}/release/tilecurv
fi
[ $# -gt 0 ] || set -- "" "--f32"

TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

"$PYTHON" -c 'import sys, laspy; laspy.read(sys.argv[1]).write(sys.argv[2], laz_backend=laspy.LazBackend.Lazrs)' \
    "$REPO/data/Haystack_Rock.las" "$TMP/Haystack_Rock.laz"
INPUTS=("$TMP/Haystack_Rock.laz" "$DATA/las/bcts_1.laz" "$DATA/las/bcts_2.laz" "$DATA/las/autzen_trim.laz")

echo "| input | points | input LAZ | options | output LAZ | output / input |"
echo "|---|---|---|---|---|---|"
for input in "${INPUTS[@]}"; do
    name=$(basename "$input")
    in_bytes=$(stat -c %s "$input")
    points=$("$PYTHON" -c 'import sys, laspy; print(laspy.open(sys.argv[1]).header.point_count)' "$input")
    for opts in "$@"; do
        out="$TMP/out.laz"
        # shellcheck disable=SC2086 # an option set is split into its words on purpose
        "$TILECURV" process "$input" -o "$out" -q $opts
        out_bytes=$(stat -c %s "$out")
        ratio=$(awk -v a="$out_bytes" -v b="$in_bytes" 'BEGIN { printf "%.2f", a / b }')
        echo "| $name | $points | $in_bytes | ${opts:-(default)} | $out_bytes | $ratio |"
        rm -f "$out"
    done
done

#!/usr/bin/env bash
# The scale study (docs/scale.md): fixed K, --radius and -k auto on six generated
# clouds with closed-form curvature (terrain clean, 2 cm noise, clean west half + 5 cm east half;
# torus; goursat; torus with isotropic noise 0.02), scored against their TrueH/TrueK columns, and
# H maps of two real surveys at K = 30 and -k auto. scripts/scale_study.py does the analysis.
#
#   bash scripts/scale_study.sh            everything -> docs/scale/ (CSV, tables) + docs/img/
#   bash scripts/scale_study.sh --quick    20k-point clouds, K in {20, 80, 320}, no maps ->
#                                          target/scale-study-quick/ (a minute)
#   bash scripts/scale_study.sh --surveys  only the real surveys' maps and their table
#
# Environment: CARGO_TARGET_DIR (where the release binary is built), STUDY_DIR (clouds and
# outputs, default target/scale-study; about 40 MB at a time), THREADS (default 2), NICE
# (default 10: the machine is shared). Needs /usr/bin/time and python3 with venv: the analysis
# venv (laspy, lazrs, numpy, matplotlib) is created in target/study-venv when missing.
# CPU time per point is user + sys of one `process` run (GNU time), so it includes reading,
# bucketing and writing the LAS; with THREADS=2 on a shared machine wall times are noisy, CPU
# times much less so.
set -euo pipefail
cd "$(dirname "$0")/.."

quick=0 clouds=1
[ "${1:-}" = --quick ] && quick=1
[ "${1:-}" = --surveys ] && clouds=0
THREADS=${THREADS:-2}
NICE=${NICE:-10}
TARGET=${CARGO_TARGET_DIR:-$PWD/target}
DIR=${STUDY_DIR:-$PWD/target/scale-study}
if [ "$quick" = 1 ]; then
    OUT=target/scale-study-quick
    IMG=$OUT
    DIR=$DIR-quick
    KS=(20 80 320)
else
    OUT=docs/scale
    IMG=docs/img
    KS=(20 30 40 80 160 320)
fi
mkdir -p "$DIR" "$OUT" "$IMG"

command -v /usr/bin/time >/dev/null || { echo "scale_study.sh: /usr/bin/time is required (apt-get install time)" >&2; exit 2; }
VENV=target/study-venv
if ! [ -x "$VENV/bin/python3" ] || ! "$VENV/bin/python3" -c 'import laspy, lazrs, numpy, matplotlib' 2>/dev/null; then
    python3 -m venv "$VENV" || { echo "scale_study.sh: python3 -m venv failed (Debian: apt-get install python3-venv)" >&2; exit 2; }
    "$VENV/bin/python3" -m pip install --quiet --disable-pip-version-check \
        'laspy[lazrs]==2.7.0' 'numpy<3' 'matplotlib<4'
fi
PY="$VENV/bin/python3 scripts/scale_study.py"

nice -n "$NICE" cargo build --release --locked --quiet
BIN=$TARGET/release/tilecurv
# -k auto is one more mode once the binary has it.
AUTO=0
"$BIN" process --help | grep -qiw auto && AUTO=1

CSV=$OUT/results.csv
if [ "$clouds" = 1 ]; then
    {
        echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
        echo "commit: $(git rev-parse --short HEAD)$(git diff --quiet || echo ' (uncommitted changes)')"
        echo "cpu: $(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n1), $(nproc) cores (shared)"
        echo "threads: $THREADS, nice $NICE"
        echo "-k auto: $([ "$AUTO" = 1 ] && echo available || echo 'not in this build: skipped')"
        echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
    } >"$OUT/machine.txt.new"
    mv "$OUT/machine.txt.new" "$OUT/machine.txt"
    $PY header >"$CSV"

    # name | generator arguments | --orient | what is scored | radii with the -k cap of each
    # (RADIUS:CAP).
    # Scoring: the terrain leaves out a border band of 11 m (one-sided neighbourhoods near the
    # square's edges: -k auto at 4 pts/m^2 reaches r_320 + r_160 + r_64, about 11 m,
    # algorithms.md 11.3). The torus is processed with --orient outward, since -k auto refuses
    # propagate (not yet supported on main): outward flips the normals where cos(theta) < -1/3, so H is
    # scored with that known sign restored and away from the two seam circles by 1.2 m along the
    # tube (r_320 = 0.78 m plus r_64 = 0.35 m at 80k points), about 2/3 of the points, outer
    # (K > 0) and inner (K < 0) parts alike. The goursat is star-shaped: outward is exact, all
    # points scored.
    # Radii: about 30, 110 and 300 points at the full size's density (terrain 4/m^2; torus 80k
    # points over 474 m^2, 169/m^2; goursat 80k over ~1840 m^2, 43/m^2); each cap is about 3x that,
    # so it binds almost nowhere, and the run's cost (the cap's k-NN query, then the cut) stays that
    # of the radius.
    if [ "$quick" = 1 ]; then
        TERRAIN_N=20k SHAPE_N=20k
    else
        TERRAIN_N=100k SHAPE_N=80k
fi
CLOUDS=(
    "terrain_clean|terrain --density 4 --points $TERRAIN_N|up|--border 11|1.5m:100 3m:350 5m:1000"
    "terrain_noise2cm|terrain --density 4 --points $TERRAIN_N --noise 0.02|up|--border 11|1.5m:100 3m:350 5m:1000"
    "terrain_half5cm|terrain --density 4 --points $TERRAIN_N --noise 0:0.05|up|--border 11|1.5m:100 3m:350 5m:1000"
    "torus|torus --points $SHAPE_N|outward|--torus-seam 1.2|0.25m:100 0.45m:350 0.75m:1000"
    "goursat|goursat --points $SHAPE_N|outward||0.5m:100 0.9m:350 1.5m:1000"
    "torus_noise0.02|torus --points $SHAPE_N --noise 0.02|outward|--torus-seam 1.2|0.25m:100 0.45m:350 0.75m:1000"
)

# run CLOUD INPUT ORIENT SCORING MODE PARAM ARGS...: one timed `process`, scored, output removed.
run() {
    local cloud=$1 input=$2 orient=$3 scoring=$4 mode=$5 param=$6
    shift 6
    local out=$DIR/out.las times
    rm -f "$out"
    times=$( { /usr/bin/time -f '%U %S %e' nice -n "$NICE" "$BIN" process "$input" -o "$out" \
        --orient "$orient" --threads "$THREADS" -q "$@" 2>&1 >/dev/null; } | tail -n1)
    [ -f "$out" ] || { echo "scale_study.sh: process $input $* failed: $times" >&2; exit 1; }
    # shellcheck disable=SC2086
    $PY measure --cloud "$cloud" --mode "$mode" --param "$param" $scoring \
        --times $times "$out" >>"$CSV"
    echo "  $cloud $mode $param: $(tail -n1 "$CSV")"
    rm -f "$out"
}

for spec in "${CLOUDS[@]}"; do
    IFS='|' read -r cloud gen orient scoring radii <<<"$spec"
    input=$DIR/$cloud.las
    # shellcheck disable=SC2086
    [ -f "$input" ] || "$BIN" generate $gen --seed 15 -q -o "$input"
    echo "$cloud ($gen, --orient $orient)"
    for k in "${KS[@]}"; do
        run "$cloud" "$input" "$orient" "$scoring" fixed "$k" -k "$k"
    done
    for rc in $radii; do
        run "$cloud" "$input" "$orient" "$scoring" radius "${rc%%:*}" --radius "${rc%%:*}" -k "${rc##*:}"
    done
    if [ "$AUTO" = 1 ]; then
        run "$cloud" "$input" "$orient" "$scoring" auto 20..320 -k auto
    fi
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" >>"$OUT/machine.txt"
$PY report --csv "$CSV" --table "$OUT/table.md" --plot "$IMG/scale_h_rms_vs_k.png"
fi

# H maps of real surveys, bare earth: bcts_1 (forested, 12-15 pts/m^2: its ground class 2,
# 48,729 of 531,662 points) and Topography (hilly terrain with water, multiple returns through
# vegetation: ground and water, classes 2 and 9, 12,054 of 73,403 points), at K = 30 and -k auto.
# Neighbourhoods are formed among the selected points only.
if [ "$quick" = 0 ]; then
    LAS=../shared/data/las
    SURVEYS=$OUT/surveys.md
    {
        echo "| survey | mode | points computed | H p2 / p50 / p98 (1/m) | H sd | chosen K | saturated | CPU us per computed point (whole file read and written) |"
        echo "|---|---|---:|---:|---:|---|---:|---:|"
    } >"$SURVEYS"
    for spec in "bcts_1|$LAS/bcts_1.laz|--classes 2" "topography|$LAS/Topography.las|--classes 2,9"; do
        IFS='|' read -r name input select <<<"$spec"
        [ -f "$input" ] || { echo "scale_study.sh: $input is missing (shared data): no maps of it" >&2; continue; }
        modes=("k30|-k 30")
        [ "$AUTO" = 1 ] && modes+=("auto|-k auto")
        for m in "${modes[@]}"; do
            IFS='|' read -r tag args <<<"$m"
            out=$DIR/${name}_$tag.las
            # shellcheck disable=SC2086
            times=$( { /usr/bin/time -f '%U %S %e' nice -n "$NICE" "$BIN" process "$input" -o "$out" \
                --threads "$THREADS" -q $select $args 2>&1 >/dev/null; } | tail -n1)
            [ -f "$out" ] || { echo "scale_study.sh: process $input $select $args failed: $times" >&2; exit 1; }
            # shellcheck disable=SC2086
            $PY survey --name "$name" --mode "$tag" --times $times "$out" >>"$SURVEYS"
            $PY map --column H --title "$name, H at $tag" --png "$IMG/${name}_H_$tag.png" "$out"
            if [ "$tag" = auto ]; then
                $PY map --column ScaleK --title "$name, K chosen by -k auto" \
                    --png "$IMG/${name}_ScaleK_auto.png" "$out"
            fi
            rm -f "$out"
        done
    done
fi
echo "scale study: $CSV, $OUT/table.md, pictures in $IMG"

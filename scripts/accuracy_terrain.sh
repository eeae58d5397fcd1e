#!/usr/bin/env bash
# Profile and plan curvature rasters: tilecurv against WhiteboxTools, both against the closed form
# (issue 27, item 5). A measured comparison, not a test: it prints a Markdown table for the README.
#
# usage: scripts/accuracy_terrain.sh                 (SEEDS="0 1 2" for three terrains)
#
# In one run, on the same points for every method:
#  1. `tilecurv generate terrain --points 400k --density 8 --terrain-truth`, clean and with
#     `--noise 0.03` (3 cm vertical; same seed, so the same x, y and the same surface);
#  2. WhiteboxTools (whitebox-workflows from PyPI): a 1 m DEM by linear TIN interpolation, then its
#     profile_curvature, plan_curvature and tangential_curvature (Florinsky's 5x5 polynomial), with
#     lidar_tin_gridding twice: on the points as they are (its grid starts at their min x / max y,
#     not on whole metres), and with two anchor points added at the whole-metre corners, which puts
#     its grid on tilecurv's, cell for cell (accuracy_terrain.py, with_corner_anchors);
#  3. tilecurv: `process -k auto --raster 1m` (cell mean), `raster --stat median` of the same
#     output, and for reference -k 30, -k 320, `-k auto --k-range 20..640` (a larger ladder),
#     the same with `--estimator jet --jet-degree 3` (a cubic fit, as Florinsky's 5x5 is), and
#     the truth columns themselves binned (what binning alone costs);
#  4. scripts/accuracy_terrain.py scores every raster at its cell centres against the generator's
#     closed form there (cells with true slope > 3 degrees, over 10 m inside the square, the same
#     cells for all), as median |error| / median |truth|, checks WhiteboxTools' sign and unit
#     against the truth, and prints the table.
# Conventions: tilecurv's ProfileCurvature and PlanCurvature and WhiteboxTools' profile_curvature and
# plan_curvature are all convex positive in 1/m (Florinsky's kv and kp), so they are compared as
# they are; the script prints the least-squares gain of each WhiteboxTools raster on the truth (1
# when sign and unit agree).
#
# Environment: TILECURV_ACCURACY_DIR (work directory, default /tmp/tilecurv-accuracy), SEEDS
# (terrain seeds, default 0, generate's default; one table each: the terrains differ much in
# slope and curvature, and so do the ratios), TILECURV (binary; default: cargo build --release).
# About 2 minutes per seed on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."

ROOT=${TILECURV_ACCURACY_DIR:-/tmp/tilecurv-accuracy}
SEEDS=${SEEDS:-0}
venv=target/venv
[ -x "$venv/bin/python3" ] || python3 -m venv "$venv"
"$venv/bin/python3" -m pip install --quiet --disable-pip-version-check \
    'laspy[lazrs]==2.7.0' 'numpy<3' 'rasterio==1.4.4' 'whitebox-workflows==2.0.6'
PY="$venv/bin/python3"
if [ -z "${TILECURV:-}" ]; then
    cargo build --release --locked --quiet
    TILECURV=${CARGO_TARGET_DIR:-$PWD/target}/release/tilecurv
fi
start=$SECONDS

# process IN LABEL ARGS...: tilecurv's terrain columns and their 1 m rasters (cell mean).
process() {
    local in=$1 label=$2
    shift 2
    local t=${in%.las}
    rm -rf "$t.$label" "$t.$label.las"
    "$TILECURV" process "$in" -o "$t.$label.las" "$@" --columns profile,plan -q \
        --raster 1m --raster-dir "$t.$label" --raster-columns ProfileCurvature,PlanCurvature
}

for SEED in $SEEDS; do
    WORK=$ROOT/seed$SEED
    mkdir -p "$WORK"
    for t in clean noise3cm; do
        noise=0
        [ "$t" = noise3cm ] && noise=0.03
        in="$WORK/$t.las"
        "$TILECURV" generate terrain -o "$in" --points 400k --density 8 --seed "$SEED" \
            --noise "$noise" --terrain-truth -q
        # WhiteboxTools runs beside tilecurv (it is mostly one thread).
        "$PY" scripts/accuracy_terrain.py wbt "$WORK" "$in" &
        wbt=$!
        process "$in" auto -k auto
        rm -rf "$WORK/$t.auto_median"
        "$TILECURV" raster "$WORK/$t.auto.las" --cell 1m --stat median -q \
            --columns ProfileCurvature,PlanCurvature -o "$WORK/$t.auto_median"
        process "$in" k30 -k 30
        process "$in" k320 -k 320
        process "$in" auto640 -k auto --k-range 20..640
        process "$in" jet3_auto640 -k auto --k-range 20..640 --estimator jet --jet-degree 3
        # The truth columns binned like the estimates: the error of a cell mean of exact values.
        mkdir -p "$WORK/$t.truth_mean"
        "$TILECURV" raster "$in" --cell 1m -q --columns TrueProfileCurvature,TruePlanCurvature \
            -o "$WORK/$t.truth_mean.tmp"
        mv "$WORK/$t.truth_mean.tmp/TrueProfileCurvature.tif" "$WORK/$t.truth_mean/ProfileCurvature.tif"
        mv "$WORK/$t.truth_mean.tmp/TruePlanCurvature.tif" "$WORK/$t.truth_mean/PlanCurvature.tif"
        rm -rf "$WORK/$t.truth_mean.tmp"
        wait "$wbt"
    done

    echo "### seed $SEED"
    echo
    "$PY" scripts/accuracy_terrain.py table "$WORK" "$SEED" | tee "$WORK/table.md"
    echo
    echo "seed $SEED: $(("$SECONDS" - start)) s since the start; rasters and accuracy.csv in $WORK"
    echo
done

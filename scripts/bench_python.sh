#!/usr/bin/env bash
# tilecurv.curvature against pgeof and jakteristics (PyPI) on the same generated terrain, in one
# Python process (scripts/bench_python.py), as ratios of their best times. Builds the wheel with
# maturin from the release build and installs it with the peers into a venv of its own.
#
# usage: scripts/bench_python.sh [POINTS]     (default 2M; K=30, THREADS=2, ROUNDS=2 from the env)
set -euo pipefail
cd "$(dirname "$0")/.."

BENCH_DIR=${TILECURV_BENCH_DIR:-/tmp/tilecurv-bench}
POINTS=${1:-2M}
mkdir -p "$BENCH_DIR"
VENV=$BENCH_DIR/pyvenv
[ -x "$VENV/bin/python3" ] || python3 -m venv "$VENV"
"$VENV/bin/python3" -m pip install --quiet --disable-pip-version-check \
    'pgeof==0.3.4' 'jakteristics==0.6.2' 'laspy[lazrs]==2.7.0' 'numpy<3' 'maturin==1.16.0'
cargo build --release --locked --quiet
target_dir=$(cargo metadata --format-version 1 --no-deps --locked |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
rm -rf "$BENCH_DIR/wheels"
"$VENV/bin/maturin" build --release --locked --quiet -m python/Cargo.toml -o "$BENCH_DIR/wheels" \
    -i "$VENV/bin/python3"
"$VENV/bin/python3" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps \
    "$BENCH_DIR"/wheels/tilecurv-*.whl
in="$BENCH_DIR/terrain_${POINTS}_seed1.las"
[ -f "$in" ] || "$target_dir/release/tilecurv" generate terrain -o "$in" --points "$POINTS" --seed 1
cat "$in" >/dev/null
"$VENV/bin/python3" scripts/bench_python.py "$in" "${K:-30}" "${THREADS:-2}" "${ROUNDS:-2}"

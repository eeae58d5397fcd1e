#!/usr/bin/env bash
# The project's test command (README, .ci/run): installs what the tests need, then checks
# formatting and lints and runs every test in release mode (the numeric tests need it).
set -euo pipefail
cd "$(dirname "$0")/.."
# laspy with its lazrs backend is the independent reader the tests cross-check outputs with;
# copclib writes the COPC test input. They go into a virtual environment (target/venv), so the
# command also works where the system Python refuses a system-wide `pip install`.
venv=target/venv
if ! [ -x "$venv/bin/python3" ]; then
  python3 -m venv "$venv" || {
    # Debian splits venv out of python3.
    apt-get install -y -q --no-install-recommends python3-venv >/dev/null && python3 -m venv "$venv"
  }
fi
# maturin builds the Python package's wheel, pytest runs its tests (python/tests).
"$venv/bin/python3" -m pip install --quiet --disable-pip-version-check \
  'laspy[lazrs]==2.7.0' 'numpy<3' 'copclib==2.6.3' 'maturin==1.16.0' 'pytest==9.2.0' \
  'rasterio==1.4.4'
export PATH="$PWD/$venv/bin:$PATH"
# Each step says its name when it fails, so that a red run says which step broke.
step() {
  local name=$1
  shift
  "$@" || {
    echo "scripts/test.sh: step '$name' failed (exit $?): $*" >&2
    exit 1
  }
}
step fmt cargo fmt --all -- --check
step clippy cargo clippy --release --all-targets --locked --workspace -- -D warnings
# The API docs build without a warning (broken links, missing docs of public items).
step docs env RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --locked --quiet
step tests cargo test --release --locked
# The binary the tests built, wherever cargo puts it (CARGO_TARGET_DIR, a workspace's target).
target_dir=$(cargo metadata --format-version 1 --no-deps --locked |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
bin=$target_dir/release/tilecurv
[ -x "$bin" ] || {
  echo "scripts/test.sh: no binary at $bin after the tests built it" >&2
  exit 1
}
# The Python package: its wheel built from the release build above (the engine crate is
# reused; the binding crate and the link are new), installed into the test venv, and its tests
# against the binary (bit-identity, bytes, events, messages, the console script).
rm -rf "$target_dir/wheels"
step wheel "$venv/bin/maturin" build --release --locked --quiet -m python/Cargo.toml \
  -o "$target_dir/wheels" -i "$venv/bin/python3"
step wheel-install "$venv/bin/python3" -m pip install --quiet --disable-pip-version-check \
  --force-reinstall --no-deps "$target_dir"/wheels/tilecurv-*.whl
step pytest env TILECURV_BIN="$bin" "$venv/bin/python3" -m pytest -q -rs -p no:cacheprovider python/tests
# The cluster test: a throwaway single-node Slurm (slurmctld, slurmd and munge from Debian's
# packages, installed when missing; needs root), a two-file job through scripts/slurm/submit.sh,
# byte-identical to `process`, then a lost task resubmitted, then one input scanned by three
# bucket tasks. Never skipped under CI=true.
if [ "$(id -u)" = 0 ] || [ "${CI:-}" = true ]; then
  step cluster bash scripts/slurm/slurm-ci.sh bash scripts/slurm/cluster_test.sh "$bin"
else
  echo "SKIPPED: the Slurm cluster test needs root (it starts slurmctld, slurmd and munged)" >&2
fi

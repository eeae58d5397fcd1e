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
"$venv/bin/python3" -m pip install --quiet --disable-pip-version-check \
  'laspy[lazrs]==2.7.0' 'numpy<3' 'copclib==2.6.3'
export PATH="$PWD/$venv/bin:$PATH"
cargo fmt --all -- --check
cargo clippy --release --all-targets --locked -- -D warnings
cargo test --release --locked
# The cluster test: a throwaway single-node Slurm (slurmctld, slurmd and munge from Debian's
# packages, installed when missing; needs root), a two-file job through scripts/slurm/submit.sh,
# byte-identical to `process`, then a lost task resubmitted. Never skipped under CI=true.
if [ "$(id -u)" = 0 ] || [ "${CI:-}" = true ]; then
  bash scripts/slurm/slurm-ci.sh bash scripts/slurm/cluster_test.sh target/release/tilecurv
else
  echo "SKIPPED: the Slurm cluster test needs root (it starts slurmctld, slurmd and munged)" >&2
fi

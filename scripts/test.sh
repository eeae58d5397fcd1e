#!/usr/bin/env bash
# The project's test command (README, .ci/run): installs what the tests need, then checks
# formatting and lints and runs every test in release mode (the numeric tests need it).
set -euo pipefail
cd "$(dirname "$0")/.."
# laspy with its lazrs backend is the independent reader the tests cross-check outputs with;
# copclib writes the COPC test input.
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore 'laspy[lazrs]==2.7.0' 'numpy<3' 'copclib==2.6.3'
cargo fmt --all -- --check
cargo clippy --release --all-targets --locked -- -D warnings
cargo test --release --locked

#!/usr/bin/env bash
# Runs one cargo-fuzz target for a time budget, at the lowest priority, with the shared data
# files (and small generated LAS/LAZ files) as its seed corpus. Prints the executions, the
# coverage and the findings (crash inputs under fuzz/artifacts/TARGET; each one becomes a
# regression test under tests/it).
#   scripts/fuzz.sh TARGET SECONDS     TARGET: las ply xyz pcd mesh
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
set -euo pipefail
target=${1:?usage: scripts/fuzz.sh TARGET SECONDS (las ply xyz pcd mesh)}
secs=${2:?usage: scripts/fuzz.sh TARGET SECONDS}
root=$(cd "$(dirname "$0")/.." && pwd)
data=$root/../shared/data
case $target in
  las) pats=('*.las' '*.laz') ;;
  ply) pats=('*.ply') ;;
  xyz) pats=('*.xyz' '*.pts' '*.txt') ;;
  pcd) pats=('*.pcd') ;;
  mesh) pats=('*.obj' '*.off') ;;
  *) echo "unknown target $target (las ply xyz pcd mesh)" >&2; exit 2 ;;
esac
seeds=$root/fuzz/seeds/$target
corpus=$root/fuzz/corpus/$target
mkdir -p "$seeds" "$corpus" "$root/fuzz/logs"
for p in "${pats[@]}"; do
  find "$data" "$root/data" -name "$p" -exec cp -n {} "$seeds/" \; 2>/dev/null || true
done
if [ "$target" = las ] && [ ! -e "$seeds/gen_200.laz" ]; then
  # Small valid files keep executions fast; the shared files are cut to -max_len anyway.
  (cd "$root" && cargo run --release --quiet -- generate terrain -o "$seeds/gen_200.laz" --points 200 -q &&
    cargo run --release --quiet -- generate terrain -o "$seeds/gen_200.las" --points 200 -q) || true
fi
if [ "$target" = mesh ] && [ ! -e "$seeds/tetra.off" ]; then
  printf 'OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n' > "$seeds/tetra.off"
fi
log=$root/fuzz/logs/$target.log
cd "$root/fuzz"
# CARGO_TARGET_DIR, when set, holds the fuzz build too (under fuzz/).
tdir=()
if [ -n "${CARGO_TARGET_DIR:-}" ]; then tdir=(--target-dir "$CARGO_TARGET_DIR/fuzz"); fi
# -O: the shipped configuration (no debug assertions): a debug_assert inside the laz crate
# (decoders.rs, `sym < 1 << 16` on garbage) otherwise stops every LAS run; the release binary
# returns an error there (tests/fuzz_findings/las-efe13bf2.laz).
nice -n 19 cargo +nightly fuzz run -O "${tdir[@]}" "$target" "$corpus" "$seeds" -- \
  -max_total_time="$secs" -max_len=65536 -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 \
  2>&1 | tee "$log" | grep -E '^(#[0-9]+.*(INITED|DONE|pulse)|Done|==[0-9]+==|stat::)' || true
echo "findings: $(find "$root/fuzz/artifacts/$target" -type f 2>/dev/null | wc -l) (fuzz/artifacts/$target); log $log"

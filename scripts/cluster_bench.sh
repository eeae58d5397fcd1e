#!/usr/bin/env bash
# cluster_bench.sh [POINTS] [FILES] [TASKS]: the cost of running as a Slurm job array instead of
# one `process`, on this machine, in one script (the baseline is `process` on the same files):
#   1. generated terrain of POINTS points (default 20M) split into FILES adjacent files (4);
#   2. `tilecurv process` on them, all cores: the baseline;
#   3. the same through scripts/slurm/submit.sh on a throwaway single-node Slurm, TASKS tile tasks
#      (16), one CPU per task (so as many tasks run at once as there are cores): wall time, and
#      the overhead per task (array wall time minus process's, over the tasks); outputs compared
#      byte for byte with process's;
#   4. the scan alone: `tilecurv bucket` serial (every bucket task in one process) against the
#      bucket array (one task per file, one CPU each).
# Needs root (Slurm) and the project's venv with laspy (bash scripts/test.sh makes it).
set -euo pipefail
cd "$(dirname "$0")/.."
points=${1:-20M} files=${2:-4} tasks=${3:-16}
cargo build --release --locked -q
tool=$PWD/target/release/tilecurv
py=$PWD/target/venv/bin/python3
[ -x "$py" ] || { echo "cluster_bench.sh: run bash scripts/test.sh once (it makes target/venv)" >&2; exit 2; }
dir=$(mktemp -d -p "${BENCH_DIR:-/tmp}" tilecurv-cbench.XXXXXX)
chmod 755 "$dir"
trap 'rm -rf "$dir"' EXIT
now() { date +%s.%N; }
secs() { awk "BEGIN { printf \"%.1f\", $2 - $1 }"; }

"$tool" generate terrain -o "$dir/t.las" --points "$points" --seed 5 -q
mkdir "$dir/parts"
"$py" scripts/split_las.py "$dir/t.las" "$dir/parts" "$files"
rm "$dir/t.las"
inputs=("$dir"/parts/part*.las)
n=$("$py" -c "import laspy,sys; print(sum(laspy.open(f).header.point_count for f in sys.argv[1:]))" "${inputs[@]}")
echo "input: $n points in $files files; $(nproc) cores"

sync; t0=$(now)
"$tool" process "${inputs[@]}" -o "$dir/ref/" -q
t1=$(now); process_s=$(secs "$t0" "$t1")
echo "process: $process_s s"

# Tiles per task for TASKS tasks: plan once with one tile per task to count the grid's tiles.
grid=$("$tool" plan "${inputs[@]}" --work "$dir/w" --tiles-per-task 1 -q | tail -n 1 | sed 's/tasks: //')
per=$(( (grid + tasks - 1) / tasks ))
export tool dir per process_s
export inputs_list="${inputs[*]}"
bash scripts/slurm/slurm-ci.sh bash -c '
  set -euo pipefail
  read -r -a inputs <<<"$inputs_list"
  now() { date +%s.%N; }
  secs() { awk "BEGIN { printf \"%.1f\", $2 - $1 }"; }
  # sbatch --wait polls at growing intervals; poll the queue every 0.2 s instead.
  drain() { while [ -n "$(squeue -h -o %i)" ]; do sleep 0.2; done; }
  sync; t0=$(now)
  bash scripts/slurm/submit.sh --tool "$tool" --work "$dir/w" -o "$dir/out/" \
    --tiles-per-task "$per" -- "${inputs[@]}" >/dev/null
  drain
  t1=$(now); array_s=$(secs "$t0" "$t1")
  ntasks=$("$tool" status --work "$dir/w" | sed -n "s/^done [0-9]* of \([0-9]*\) tasks$/\1/p")
  same=identical
  for f in "$dir"/ref/*.las; do cmp -s "$f" "$dir/out/$(basename "$f")" || same=DIFFERENT; done
  echo "array: $array_s s for plan + $(ls "${inputs[@]}" | wc -l) bucket tasks + $ntasks tile tasks + assemble (outputs $same to process)"
  awk -v a="$array_s" -v p="$process_s" -v t="$ntasks" "BEGIN {
    printf \"array / process wall time: %.2f; overhead per tile task: %.2f s\n\", a / p, (a - p) / t }"
  # The scan alone: serial against the array.
  rm -rf "$dir/w/buckets"; sync; t0=$(now)
  "$tool" bucket --work "$dir/w" -q
  t1=$(now); serial_s=$(secs "$t0" "$t1")
  rm -rf "$dir/w/buckets"; mkdir -p "$dir/w/log"; sync; t0=$(now)
  sbatch --parsable --array=0-$((${#inputs[@]} - 1)) -c 1 -o "$dir/w/log/b-%a.log" \
    --wrap "$tool bucket --work $dir/w --task \$SLURM_ARRAY_TASK_ID -q" >/dev/null
  drain
  t1=$(now); barray_s=$(secs "$t0" "$t1")
  awk -v s="$serial_s" -v a="$barray_s" "BEGIN {
    printf \"scan: serial %.1f s, array %.1f s: array / serial %.2f\n\", s, a, a / s }"
'

#!/usr/bin/env bash
# cluster_test.sh TOOL: the cluster test, run inside a throwaway Slurm (scripts/slurm/slurm-ci.sh,
# which exports SLURM_CONF): a two-file, multi-tile job through submit.sh must give outputs
# byte-identical to `tilecurv process`; then one task's results are deleted, assemble must refuse
# with exit 5 naming it, `status --missing` must name it, and resubmitting only that task must
# give the same bytes again; last, one LAZ input scanned by three bucket tasks of the array
# (--points-per-scan-task) must give process's bytes too. Prints `N passed, N failed` and exits
# non-zero on any failure.
set -euo pipefail
tool=$(readlink -f "$1")
here=$(cd "$(dirname "$0")" && pwd)
dir=$(mktemp -d -t tilecurv-cluster.XXXXXX)
chmod 755 "$dir"
trap '[ "${KEEP:-0}" = 1 ] || rm -rf "$dir"' EXIT
cd "$dir"
passed=0 failed=0
check() {   # check NAME COMMAND...: runs the command, counts it
  if "${@:2}"; then passed=$((passed + 1)); echo "ok: $1"
  else failed=$((failed + 1)); echo "FAILED: $1"; fi
}

# Two overlapping generated surveys: one scene, neighbourhoods cross the file border.
"$tool" generate terrain -o a.las --points 40k --seed 1 -q
"$tool" generate terrain -o b.laz --points 30k --seed 2 --density 6 -q
opts=(--tile 15m)
"$tool" process a.las b.laz -o ref/ "${opts[@]}" -q

same_outputs() {   # same_outputs DIR: both outputs in DIR byte-identical to process's
  cmp "$1/a.las" ref/a.las && cmp "$1/b.laz" ref/b.laz
}

t0=$(date +%s.%N)
bash "$here/submit.sh" --tool "$tool" --work "$dir/w" -o "$dir/out/" --tiles-per-task 3 \
  --wait -- a.las b.laz "${opts[@]}"
t1=$(date +%s.%N)
echo "array run: $(awk "BEGIN { print $t1 - $t0 }") s"
tasks=$("$tool" plan a.las b.laz --work "$dir/w" "${opts[@]}" --tiles-per-task 3 -q | tail -n 1)
check "status after the array: done N of N (${tasks})" \
  grep -qx "done ${tasks#tasks: } of ${tasks#tasks: } tasks" <("$tool" status --work "$dir/w")
check "array outputs are byte-identical to process" same_outputs out
check "status --missing prints nothing when complete" test -z "$("$tool" status --work "$dir/w" --missing)"

# Lose one task's results: assemble refuses, status names the task, a resubmission fixes it.
victim=$(ls w/results/*.res | sed -n 5p)
rm "$victim"
rc=0; "$tool" assemble --work "$dir/w" -o "$dir/partial/" -q 2> assemble.err || rc=$?
check "assemble exits 5 while a task is missing" test "$rc" = 5
check "assemble wrote nothing" test ! -e partial/a.las
missing=$("$tool" status --work "$dir/w" --missing)
check "status --missing names one task ($missing)" grep -Eqx '[0-9]+' <<<"$missing"
check "assemble's error names the same task" grep -q "run-tile tasks not done: $missing;" assemble.err
resubmitted=$(bash "$here/submit.sh" --tool "$tool" --resubmit --work "$dir/w" -o "$dir/out2/" --wait)
echo "$resubmitted"
check "resubmitted outputs are byte-identical to process" same_outputs out2
job=$(sed -n 's/^run-tile array (tasks [0-9,-]*): //p' <<<"$resubmitted")
check "the resubmitted array ran task $missing alone" \
  test "$(cd w/log && ls tile-"$job"_*.log)" = "tile-${job}_$missing.log"

# One input split between bucket tasks: 130k points in LASzip chunks of 50k, 40k points a task
# cut at the chunk starts nearest 32.5k, 65k and 97.5k: 50k and 100k, three tasks.
"$tool" generate terrain -o c.laz --points 130k --seed 3 -q
"$tool" process c.laz -o ref/c.laz "${opts[@]}" -q
mkdir -p out3
split=$(bash "$here/submit.sh" --tool "$tool" --work "$dir/w3" -o "$dir/out3/c.laz" \
  --points-per-scan-task 40k --tiles-per-task 8 --wait -- c.laz "${opts[@]}" 2>&1)
echo "$split"
check "plan split the one input into 3 bucket tasks" grep -q "^plan: 3 bucket tasks" <<<"$split"
bucket_job=$(sed -n 's/^bucket array: //p' <<<"$split")
check "the bucket array ran 3 tasks" test "$(cd w3/log && ls bucket-"$bucket_job"_*.log | wc -l)" = 3
check "split-scan output is byte-identical to process" cmp out3/c.laz ref/c.laz

echo "cluster: $passed passed, $failed failed"
[ "$failed" = 0 ]

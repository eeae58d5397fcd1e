#!/usr/bin/env bash
# submit.sh: run `tilecurv` on a Slurm cluster as job arrays.
#
#   scripts/slurm/submit.sh --work W -o OUT [options] -- INPUTS... [process options that change results]
#   scripts/slurm/submit.sh --resubmit --work W -o OUT [options]
#
# The first form runs `tilecurv plan` here (on the submit host), then submits a bucket array (one
# task per input file, or per range of points of a large LAS/LAZ one), a run-tile array (one task
# per group of tiles) and assemble, chained with --dependency=afterany: assemble checks that
# every tile is done itself and exits 5, naming the missing tasks and writing nothing, when one
# failed. The second form resubmits only the tile tasks `tilecurv status --missing` lists, then
# assemble. W must be on a file system every node sees at the same path; OUT is a file for one
# input, a directory (ending in /) for several.
#
# Options:
#   --tool PATH          the tilecurv binary as the nodes see it (default: tilecurv on PATH)
#   --tiles-per-task K   tiles per run-tile task (default: plan's, raised so the array fits
#                        the cluster's MaxArraySize)
#   --points-per-scan-task N  points of one input per bucket task (default: plan's, 50M)
#   --cpus N             CPUs per task (sbatch -c; the tool's threads follow SLURM_CPUS_PER_TASK)
#   --mem M              memory per task for sbatch --mem (e.g. 16G); the tool gets --memory at
#                        half of it
#   --max-running R      at most R tasks of an array at once (--array=...%R)
#   --logs DIR           where task logs go (default: W/log)
#   --wait               wait for assemble and exit with its exit code
#   --sbatch "ARGS"      extra arguments for every sbatch (partition, account, time, ...)
set -euo pipefail

tool=tilecurv work= out= tiles_per_task= per_scan= cpus=1 mem= max_running= logs= wait=0 resubmit=0 extra=
while [ $# -gt 0 ]; do
  case "$1" in
    --tool) tool=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    -o|--output) out=$2; shift 2 ;;
    --tiles-per-task) tiles_per_task=$2; shift 2 ;;
    --points-per-scan-task) per_scan=$2; shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    --mem) mem=$2; shift 2 ;;
    --max-running) max_running=$2; shift 2 ;;
    --logs) logs=$2; shift 2 ;;
    --wait) wait=1; shift ;;
    --resubmit) resubmit=1; shift ;;
    --sbatch) extra=$2; shift 2 ;;
    --) shift; break ;;
    *) echo "submit.sh: unknown option $1 (see the header of $0)" >&2; exit 2 ;;
  esac
done
[ -n "$work" ] && [ -n "$out" ] || { echo "submit.sh: --work and -o are required" >&2; exit 2; }
[ $resubmit = 1 ] || [ $# -gt 0 ] || { echo "submit.sh: no inputs after --" >&2; exit 2; }
logs=${logs:-$work/log}

# sbatch options shared by every job; the tool's memory budget is half of --mem.
common=(--parsable -c "$cpus")
memory_opt=
if [ -n "$mem" ]; then
  common+=(--mem="$mem")
  memory_opt="--memory $(( $(numfmt --from=iec "$mem") / 2 ))"
fi
# shellcheck disable=SC2206
[ -z "$extra" ] || common+=($extra)
cap() { [ -n "$max_running" ] && echo "%$max_running" || true; }

submit_tiles() {   # $1: the --array spec; prints the job id
  sbatch "${common[@]}" --array="$1$(cap)" -o "$logs/tile-%A_%a.log" $2 \
    --wrap "$tool run-tile --work $work --task \$SLURM_ARRAY_TASK_ID $memory_opt -q"
}

submit_assemble() {   # $1: dependency or empty; prints the job id (waits with --wait)
  local opts=()
  [ $wait = 0 ] || opts+=(--wait)
  [ -z "$1" ] || opts+=(--dependency="$1")
  sbatch "${common[@]}" "${opts[@]}" -o "$logs/assemble-%j.log" \
    --wrap "$tool assemble --work $work -o $out $memory_opt -q"
}

if [ $resubmit = 1 ]; then
  mkdir -p "$logs"   # a missing -o directory makes every task fail before it starts
  missing=$("$tool" status --work "$work" --missing)
  dep=
  if [ -n "$missing" ]; then
    t=$(submit_tiles "$missing" "")
    echo "run-tile array (tasks $missing): $t"
    dep=afterany:$t
  else
    echo "submit.sh: every tile task is done; submitting assemble" >&2
  fi
  rc=0; a=$(submit_assemble "$dep") || rc=$?
  echo "assemble job: $a"
  exit $rc
fi

plan() {   # plans (with --tiles-per-task, --points-per-scan-task if set); sets buckets, per, tasks
  local o
  o=$("$tool" plan "$@" --work "$work" ${tiles_per_task:+--tiles-per-task "$tiles_per_task"} \
    ${per_scan:+--points-per-scan-task "$per_scan"} -q)
  buckets=$(sed -n 's/^bucket tasks: //p' <<<"$o")
  per=$(sed -n 's/^tiles per task: //p' <<<"$o")
  tasks=$(tail -n 1 <<<"$o" | sed -n 's/^tasks: //p')
  [ -n "$buckets" ] && [ -n "$per" ] && [ -n "$tasks" ] || {
    echo "submit.sh: plan printed no task counts" >&2; exit 1; }
}
plan "$@"
# The cluster's array limit: indexes 0 .. MaxArraySize - 1.
max=$(scontrol show config 2>/dev/null | sed -n 's/^MaxArraySize *= *//p')
max=${max:-1001}
if [ "$tasks" -gt "$max" ]; then
  # Enough tiles per task for the array to fit: T = ceil(grid / K) <= max.
  grid=$(( tasks * per ))
  tiles_per_task=$(( (grid + max - 1) / max ))
  echo "submit.sh: $tasks tasks exceed MaxArraySize $max: re-planning with --tiles-per-task $tiles_per_task" >&2
  plan "$@"
fi
if [ "$buckets" -gt "$max" ]; then
  # Bucket tasks are inputs and ranges of their points: fewer only with larger ranges.
  echo "submit.sh: $buckets bucket tasks exceed MaxArraySize $max: pass a larger --points-per-scan-task (or fewer inputs)" >&2
  exit 2
fi
echo "plan: $buckets bucket tasks, $tasks tile tasks in $work" >&2
mkdir -p "$logs"   # after plan (which clears a work directory of other runs)

b=$(sbatch "${common[@]}" --array="0-$((buckets - 1))$(cap)" -o "$logs/bucket-%A_%a.log" \
      --wrap "$tool bucket --work $work --task \$SLURM_ARRAY_TASK_ID $memory_opt -q")
echo "bucket array: $b"
t=$(submit_tiles "0-$((tasks - 1))" "--dependency=afterany:$b")
echo "run-tile array: $t"
rc=0; a=$(submit_assemble "afterany:$t") || rc=$?
echo "assemble job: $a"
exit $rc

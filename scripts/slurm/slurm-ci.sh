#!/usr/bin/env bash
# slurm-ci.sh [CMD ARGS...]: start a throwaway single-node Slurm (Debian 12, root, no systemd), run CMD
# with SLURM_CONF exported (default: the self-test), then stop every process by PID; exits with CMD's status.
set -euo pipefail
ms() { local t=${EPOCHREALTIME/[.,]/}; echo $((t / 1000)); }; die() { echo "[slurm-ci] FAIL: $*" >&2; exit 1; }
T0=$(ms); step() { local t; t=$(ms); echo "[slurm-ci] $1: $((t - T0)) ms" >&2; T0=$t; }
if ! { command -v slurmctld && command -v slurmd && command -v sbatch && command -v munged; } >/dev/null; then
  apt_i() { DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -q \
              --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null; }
  apt_i || { apt-get -o DPkg::Lock::Timeout=600 update -q >/dev/null && apt_i; }; step "install"; fi
R=$(mktemp -d -t slurm-ci.XXXXXX); chmod 755 "$R"   # munged wants its socket dir searchable by all
mkdir -p "$R"/{munge,state,spool,log,run,work}
export SLURM_CONF=$R/slurm.conf; PIDS=()   # all clients and daemons read only this; PIDS: munged, ctld, slurmd
slurm_down() {
  set +eu; local p i e; T0=$(ms)
  if [ ${#PIDS[@]} -ge 2 ] && kill -0 "${PIDS[1]}" 2>/dev/null; then
    timeout 10 scancel --quiet --user=root         # `scontrol shutdown` alone orphans running jobs
    for i in $(seq 50); do [ -z "$(timeout 5 squeue -h 2>/dev/null)" ] && break; sleep 0.2; done
    timeout 10 scontrol shutdown >/dev/null 2>&1   # stops slurmctld and slurmd
  fi
  for p in "${PIDS[@]:1}" "${PIDS[@]:0:1}"; do     # slurm daemons first, munged last
    [ "$p" = "${PIDS[0]}" ] && kill "$p" 2>/dev/null
    for i in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
    kill -0 "$p" 2>/dev/null && { kill "$p"; sleep 1; kill -9 "$p" 2>/dev/null; }
  done
  for p in /proc/[0-9]*; do   # leftovers carrying our SLURM_CONF: slurmstepd (ignores TERM), jobs, CMD
    mapfile -d '' -t e 2>/dev/null < "$p/environ" || continue
    [[ " ${e[*]} " == *" SLURM_CONF=$SLURM_CONF "* ]] && kill -9 "${p#/proc/}" 2>/dev/null
  done
  rm -rf "$R"; step "teardown"
}
trap 'rc=$?; slurm_down; exit $rc' EXIT; trap 'exit 130' INT; trap 'exit 143' TERM
head -c 1024 /dev/urandom > "$R/munge/key"; chmod 400 "$R/munge/key"   # root's munged: root's key
/usr/sbin/munged --socket="$R/munge/sock" --key-file="$R/munge/key" --seed-file="$R/munge/seed" \
  --pid-file="$R/run/munged.pid" --log-file="$R/log/munged.log"
PIDS+=("$(cat "$R/run/munged.pid")"); step "munged up"
busy() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }; PORT=${SLURM_CI_PORT:-}   # a free port pair
for i in $(seq 20); do [ -n "$PORT" ] && break; PORT=$((20000 + RANDOM % 5000 * 2))
  if busy "$PORT" || busy $((PORT + 1)); then PORT=; fi; done
[ -n "$PORT" ] || die "no free port pair"
cat > "$SLURM_CONF" <<CONF
ClusterName=ci
SlurmctldHost=localhost
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
# defaults kept: AuthType/CredType munge, SlurmdUser=root, no accounting, MpiDefault=none
AuthInfo=socket=$R/munge/sock
StateSaveLocation=$R/state
SlurmdSpoolDir=$R/spool
SlurmctldPidFile=$R/run/slurmctld.pid
SlurmdPidFile=$R/run/slurmd.pid
SlurmctldLogFile=$R/log/slurmctld.log
SlurmdLogFile=$R/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
DependencyParameters=kill_invalid_depend
EnforcePartLimits=ALL
ReturnToService=2
${SLURM_CI_EXTRA_CONF:-}
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo) State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -f "$SLURM_CONF"; slurmd -f "$SLURM_CONF" -N localhost
for f in slurmctld slurmd; do
  for i in $(seq 50); do [ -s "$R/run/$f.pid" ] && break; sleep 0.1; done
  [ -s "$R/run/$f.pid" ] || die "$f did not start: $(tail -5 "$R/log/$f.log")"; PIDS+=("$(cat "$R/run/$f.pid")")
done
for i in $(seq 100); do   # bounded (~20 s); a client call blocks ~10 s when slurmctld is gone
  kill -0 "${PIDS[1]}" 2>/dev/null || die "slurmctld exited: $(tail -5 "$R/log/slurmctld.log")"
  [ "$(timeout 5 sinfo -h -N -o %T 2>/dev/null)" = idle ] && break; sleep 0.2
done
[ "$(timeout 5 sinfo -h -N -o %T)" = idle ] || die "node not idle: $(sinfo -N -o '%N %T %E')"
step "slurmctld + slurmd up, node idle (port $PORT)"
wait_jobs() {   # bounded poll until none of the given jobs is pending or running
  local ids out end=$((SECONDS + ${SLURM_CI_WAIT:-120})); ids=$(IFS=,; echo "$*")
  while out=$(timeout 10 squeue -h -j "$ids" -o %T) && [ -n "$out" ]; do
    [ $SECONDS -lt $end ] || { squeue; die "timeout waiting for jobs $ids"; }; sleep 0.2; done
  [ -z "$out" ] || die "squeue failed"; }
job_info() {    # "TASK STATE EXIT " per array task ("-" for a plain job); kept for MinJobAge (300 s)
  timeout 10 scontrol -o show job "$1" | awk '{t = "-"; for (i = 1; i <= NF; i++) { split($i, kv, "=")
    if (kv[1] == "ArrayTaskId") t = kv[2]; if (kv[1] == "JobState") s = kv[2]; if (kv[1] == "ExitCode") e = kv[2] }
    print t, s, e}' | sort | tr '\n' ' '
}
selftest() {    # array with one failing task -> afterany check names it -> resubmit only that index
  cd "$R/work"; touch fail-2
  local a c task='i=$SLURM_ARRAY_TASK_ID; [ ! -e fail-$i ] || exit 1
    echo "task $i cpus=${SLURM_CPUS_PER_TASK:-unset}" > tile-$i.tmp && mv tile-$i.tmp tile-$i.out'
  local check='m=; for i in 0 1 2 3; do [ -e tile-$i.out ] || m=${m:+$m,}$i; done
    rm -f missing; [ -z "$m" ] || { echo "$m" > missing; exit 3; }; cat tile-?.out > assembled'
  a=$(sbatch --parsable --array=0-3 -c 1 -o 'task-%a.log' --wrap "$task")
  c=$(sbatch --parsable --dependency=afterany:"$a" -o check.log --wrap "$check")
  wait_jobs "$a" "$c"; step "array 0-3 (task 2 fails) + afterany check"
  [ "$(job_info "$a")" = "0 COMPLETED 0:0 1 COMPLETED 0:0 2 FAILED 1:0 3 COMPLETED 0:0 " ] || die "array"
  [ "$(job_info "$c")" = "- FAILED 3:0 " ] && [ "$(cat missing)" = 2 ] || die "check: $(job_info "$c")"
  rm fail-2
  a=$(sbatch --parsable --array="$(cat missing)" -c 1 -o 'task-%a.log' --wrap "$task")
  c=$(sbatch --parsable --dependency=afterany:"$a" -o check.log --wrap "$check")
  wait_jobs "$a" "$c"; step "resubmit --array=2 + check"
  [ "$(job_info "$a")$(job_info "$c")" = "2 COMPLETED 0:0 - COMPLETED 0:0 " ] || die "resubmit"
  [ "$(sed -n 3p assembled)" = "task 2 cpus=1" ] && [ "$(wc -l < assembled)" = 4 ] || die "assembled"
  echo "[slurm-ci] self-test passed" >&2
}
if [ $# -gt 0 ]; then "$@" & wait $!; else selftest; fi   # `& wait` lets a TERM stop us at once

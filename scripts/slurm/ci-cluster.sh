#!/usr/bin/env bash
# CI: a one-node Slurm cluster on localhost (munged, slurmctld, slurmd; Debian's slurm-wlm and
# munge, installed by scripts/setup.sh) runs a 4-shard library sweep as a job array
# (calibrate-library.sbatch) and its merge (merge-library.sbatch), then a 3-shard stability map
# (lab-sweep.sbatch, lab-merge.sbatch); each merged result must equal a single-process run of
# the same sweep byte for byte. A small, fast setting (four recipes,
# cell surrogate only, 12 points, one Poisson ratio) keeps it to seconds. Needs root (the daemons). Run from
# anywhere: scripts/slurm/ci-cluster.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-${BUILD_DIR:-build}}
lab=$(realpath "$build/bin/conica-lab")
data=$(realpath ../shared/data/phantoms)
work=$(mktemp -d /tmp/conica-slurm.XXXXXX)
conf=$work/etc
mkdir -p "$conf" "$work/state" "$work/spool" "$work/log" "$work/munge"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

# munge: a key for this run only.
dd if=/dev/urandom bs=1 count=1024 of="$work/munge/munge.key" status=none
chmod 600 "$work/munge/munge.key"
munged --force --key-file="$work/munge/munge.key" --socket="$work/munge/socket" \
  --pid-file="$work/munge/pid" --log-file="$work/munge/log" --seed-file="$work/munge/seed"
pids+=("$(cat "$work/munge/pid")")

cpus=$(nproc)
cat > "$conf/slurm.conf" <<CONF
ClusterName=conica-ci
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge/socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
NodeName=localhost CPUs=$cpus State=UNKNOWN
PartitionName=ci Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$conf/slurm.conf
slurmctld -D -f "$SLURM_CONF" >"$work/log/slurmctld.out" 2>&1 &
pids+=("$!")
slurmd -D -N localhost -f "$SLURM_CONF" >"$work/log/slurmd.out" 2>&1 &
pids+=("$!")
for _ in $(seq 60); do
  sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)' && break
  sleep 0.5
done
sinfo -h -o "%P %T %c" || { cat "$work"/log/*; exit 1; }

# Waits (at most 2 min) until the jobs of a comma-separated list have left the queue.
wait_jobs() {
  for _ in $(seq 240); do
    [[ -z $(squeue -h -j "$1" 2>/dev/null) ]] && return 0
    sleep 0.5
  done
}

args=(--scene "$PWD/configs/phantom-cylinder.pbtxt" --data-dir "$data"
      --recipes EF10_0T,EF30_0T,EF30_50T,EF50_50T --full-iterations -1 --points 12
      --poisson-grid 1 --threads 1)
# The sweep on the cluster: 4 array tasks, then the merge once they all succeeded.
cd "$work"
export CONICA_LAB=$lab
array=$(sbatch --parsable --array=0-3 --cpus-per-task=1 \
  "$OLDPWD/scripts/slurm/calibrate-library.sbatch" "${args[@]}" --out "$work/cluster")
merge=$(sbatch --parsable --dependency=afterok:"$array" \
  "$OLDPWD/scripts/slurm/merge-library.sbatch" "${args[@]}" --out "$work/cluster")
wait_jobs "$array,$merge"
cat "$work"/conica-library-*.out
[[ -f $work/cluster/index.csv ]] || { echo "ci-cluster: the merge wrote no index"; cat "$work"/log/*; exit 1; }
# The same sweep in one process.
"$lab" library "${args[@]}" --out "$work/single" >/dev/null
"$lab" library "${args[@]}" --out "$work/single" --merge >/dev/null
diff -r -x logs "$work/single" "$work/cluster"
echo "ci-cluster: 4-shard Slurm library equals the single-process one ($(ls "$work/cluster"/*.card | wc -l) cards)"

# A stability map (short runs) as a 3-task array and its merge, against one process.
stab=(stability --seconds 0.005 --no-plot)
array=$(sbatch --parsable --array=0-2 --cpus-per-task=1 \
  "$OLDPWD/scripts/slurm/lab-sweep.sbatch" "${stab[@]}" --out "$work/stab-cluster")
merge=$(sbatch --parsable --dependency=afterok:"$array" \
  "$OLDPWD/scripts/slurm/lab-merge.sbatch" "${stab[@]}" --out "$work/stab-cluster")
wait_jobs "$array,$merge"
cat "$work"/conica-sweep-*.out
[[ -f $work/stab-cluster.csv ]] || { echo "ci-cluster: the stability merge wrote no CSV"; cat "$work"/log/*; exit 1; }
"$lab" "${stab[@]}" --out "$work/stab-single" >/dev/null
cmp "$work/stab-single.csv" "$work/stab-cluster.csv"
echo "ci-cluster: 3-shard Slurm stability map equals the single-process one ($(($(wc -l < "$work/stab-cluster.csv") - 1)) rows)"

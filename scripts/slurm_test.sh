#!/usr/bin/env bash
# The batch farm of docs/batch-bake.md on a real scheduler: a single-node Slurm (munge,
# slurmctld, slurmd) in a private directory, the documented job array and merge job (the
# scripts are cut out of the docs, not copied, so the docs cannot drift), one task killed and
# retried as the docs say, and the merged file compared with a single bake byte for byte. Also
# validates the docs' Kubernetes Job against the API's Job schema (no cluster runs it here).
#
#   scripts/slurm_test.sh [CSSM_BINARY]     (default: target/release/cssm)
#
# Installs Slurm and munge (Debian's slurm-wlm, munge) and kubernetes-validate (PyPI) where
# missing, as scripts/test.sh installs lavapipe. Nothing outside a temporary directory is
# touched: the daemons get their own configuration, key, sockets, ports, state and logs.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
cssm=$(realpath "${1:-target/release/cssm}")
docs=docs/batch-bake.md

SUDO=""
[[ $(id -u) -ne 0 ]] && SUDO="sudo"
if ! command -v slurmctld >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
    echo "no Slurm found: installing slurm-wlm and munge (the batch-farm test)" >&2
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq slurm-wlm munge
fi
if ! command -v kubernetes-validate >/dev/null 2>&1; then
    echo "no kubernetes-validate found: installing it from PyPI (the Job manifest's schema)" >&2
    python3 -m pip install -q kubernetes-validate
fi

work=$(mktemp -d)
cleanup() {
    for pid in "$work"/slurmd.pid "$work"/slurmctld.pid "$work"/munge/pid; do
        [[ -s $pid ]] && kill "$(cat "$pid")" 2>/dev/null || true
    done
    sleep 0.5
    rm -rf "$work"
}
trap cleanup EXIT
fail() {
    echo "slurm_test: $*" >&2
    for log in "$work"/log/*.log "$work"/logs/*.log; do
        [[ -f $log ]] && { echo "--- $log" >&2; tail -n 20 "$log" >&2; }
    done
    exit 1
}

# The code block under the docs' `<!-- slurm: NAME -->` marker.
extract() {
    awk -v marker="<!-- slurm: $1 " '
        index($0, marker) == 1 { found = 1; next }
        found && /^```/ { if (inside) exit; inside = 1; next }
        inside { print }' "$docs"
}
mkdir -p "$work"/{munge,state,spool,log,logs,parts,bin}
extract bake.sh >"$work/bake.sh"
extract merge.sh >"$work/merge.sh"
grep -q 'cssm bake' "$work/bake.sh" || fail "no bake.sh under its marker in $docs"
grep -q 'cssm merge' "$work/merge.sh" || fail "no merge.sh under its marker in $docs"

# The docs' Kubernetes Job, against the Job schema (unknown fields refused).
awk '/^## A Kubernetes indexed Job/ { found = 1 }
     found && /^```yaml/ { inside = 1; next }
     inside && /^```/ { exit }
     inside { print }' "$docs" >"$work/job.yaml"
[[ -s $work/job.yaml ]] || fail "no Kubernetes Job in $docs"
kubernetes-validate --strict --quiet "$work/job.yaml" || fail "the docs' Kubernetes Job is not a valid Job"

# munge: a key of our own, a socket in the directory.
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 700 "$work/munge" && chmod 600 "$work/munge/munge.key"
munged --force --socket="$work/munge/sock" --key-file="$work/munge/munge.key" \
    --log-file="$work/munge/log" --pid-file="$work/munge/pid" --seed-file="$work/munge/seed"

# Slurm: this machine as the one node, ports of this process's own (two runs at once do not meet).
host=$(hostname -s)
port=$((20000 + ($$ % 20000) * 2))
cat >"$work/slurm.conf" <<EOF
ClusterName=cssmtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=$(id -un)
SlurmdUser=$(id -un)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge/sock
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MinJobAge=600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$work/slurm.conf
slurmctld -c -i
slurmd
for _ in $(seq 60); do
    sinfo -h -o %T 2>/dev/null | grep -q idle && break
    sleep 0.5
done
sinfo -h -o %T | grep -q idle || fail "the Slurm node did not come up"

# The job state of `id` (a job, or an array task `id_i`).
state() { scontrol -o show job "$1" | tr ' ' '\n' | sed -n 's/^JobState=//p' | sort -u | paste -sd,; }
reason() { scontrol -o show job "$1" | tr ' ' '\n' | sed -n 's/^Reason=//p'; }
# Waits until job `id` (every task of it) has ended; fails after `limit` seconds.
wait_done() {
    local id=$1 limit=${2:-300} start=$SECONDS
    while squeue -h -j "$id" 2>/dev/null | grep -q .; do
        ((SECONDS - start < limit)) || fail "job $id still running after $limit s"
        sleep 1
    done
}

# The farm: 3 chunks of the Cornell box at atlas 512 (three segments of depth maps, so every
# chunk bakes some), run from the submission directory as a user would.
cp "$cssm" "$work/bin/cssm"
export PATH="$work/bin:$PATH" N=3 SCENE="$repo/scenes/cornell-box" PARTS="$work/parts" \
    ATLAS=512 CUBE=8 BAKE_OPTIONS="--traversal spiral" OUT="$work/merged.cssm"
cd "$work"
array=$(sbatch --parsable --array=0-2 --cpus-per-task=1 bake.sh)
merge=$(sbatch --parsable --dependency=afterok:"$array" merge.sh)
# A task lost once: killed while it runs (a pending task cancelled leaves no record to check).
for _ in $(seq 600); do
    [[ $(state "${array}_1") == RUNNING ]] && break
    sleep 0.1
done
[[ $(state "${array}_1") == RUNNING ]] || fail "task 1 never ran: $(state "${array}_1")"
scancel "${array}_1"
wait_done "$array"
[[ $(state "${array}_1") == CANCELLED ]] || fail "task 1: $(state "${array}_1"), expected CANCELLED"
for i in 0 2; do
    [[ $(state "${array}_$i") == COMPLETED ]] || fail "task $i: $(state "${array}_$i")"
done
# The docs: the merge stays pending, its dependency never satisfied.
for _ in $(seq 30); do
    [[ $(reason "$merge") == DependencyNeverSatisfied ]] && break
    sleep 1
done
[[ $(state "$merge") == PENDING && $(reason "$merge") == DependencyNeverSatisfied ]] ||
    fail "merge job: $(state "$merge") ($(reason "$merge")), expected PENDING (DependencyNeverSatisfied)"
[[ ! -e merged.cssm ]] || fail "merged before every chunk was there"
# The docs' retry: cancel the merge, rerun the failed task alone, merge after it.
scancel "$merge"
retry=$(sbatch --parsable --array=1 --cpus-per-task=1 bake.sh)
merge=$(sbatch --parsable --dependency=afterok:"$retry" merge.sh)
wait_done "$retry"
wait_done "$merge"
[[ $(state "$merge") == COMPLETED ]] || fail "merge job after the retry: $(state "$merge")"

# The same bake in one piece, compared byte for byte.
cssm bake "$SCENE" --atlas "$ATLAS" --cube "$CUBE" $BAKE_OPTIONS -o single.cssm >/dev/null 2>&1
cmp merged.cssm single.cssm || fail "the merged file differs from the single bake"
echo "slurm_test: 3 chunks on Slurm (one killed, retried), merged by a dependent job: identical" \
    "to the single bake ($(stat -c %s single.cssm) bytes); the Kubernetes Job is valid"

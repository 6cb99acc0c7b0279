#!/usr/bin/env bash
# The Slurm recipe of docs/datasets.md (examples/slurm/dataset.sbatch and merge.sbatch), run end to end on a
# real single-node Slurm cluster that this script makes in a temporary folder and takes down again:
#
#   1. munged, slurmctld and slurmd start from a slurm.conf of their own (SLURM_CONF), with a
#      munge key made for the run, spool and state folders in the temporary folder, free ports;
#      Debian's slurm-wlm and munge are installed when absent (as root, with apt-get);
#   2. the job array renders SHARDS shards of a labelled dataset (YOLO labels on every image) into
#      one shared folder, and the merge-and-verify job is submitted with --dependency=afterok on it;
#   3. a node that dies: one array task is requeued and its uwnr process sent SIGKILL mid-run;
#      a task that fails: another is cancelled mid-run, which leaves the merge job waiting forever,
#      and is resubmitted with a new merge job, as docs/datasets.md says; the script checks that both
#      shards' last runs kept the pairs already made;
#   4. the same command runs on one machine without --shard, and the merged folder is compared
#      with it file by file. The last line says whether they are byte-identical; the exit status
#      is non-zero if they are not, or if any step failed.
#
#   bash tools/slurm_e2e.sh                       # uwnr from UWNR_BIN, else the PATH, else target/
#   UWNR_BIN=target/debug/uwnr bash tools/slurm_e2e.sh
#
# Settings (environment): UWNR_BIN; DATA (default ../shared/data: the clean images come from its
# inair/, the references from references/u45); IMAGES (clean images, default 32); SHARDS (4);
# PER_IMAGE (2); SIZE (the render size, default 384x384); KILL_TASK (the task killed, default 1;
# the next one is cancelled);
# KEEP=1 keeps the temporary folder. Without the data folder, or without Slurm and no way to
# install it, the script says why and exits 0 without testing (SLURM_E2E_REQUIRED=1: exit 1).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
DATA=${DATA:-../shared/data}
IMAGES=${IMAGES:-32}
SHARDS=${SHARDS:-4}
PER_IMAGE=${PER_IMAGE:-2}
SIZE=${SIZE:-384x384}
KILL_TASK=${KILL_TASK:-1}
# How long the cluster may take to do anything at all before the run is declared stuck.
DEADLINE_S=${DEADLINE_S:-900}

say() { echo "slurm_e2e: $*" >&2; }
skip() {
    say "skipped: $*"
    if [ "${SLURM_E2E_REQUIRED:-0}" = 1 ]; then exit 1; fi
    echo "slurm_e2e: SKIPPED ($*)"
    exit 0
}
die() {
    say "FAILED: $*"
    echo "slurm_e2e: FAILED: $*"
    exit 1
}

# --- the binary and the data --------------------------------------------------------------------
if [ -n "${UWNR_BIN:-}" ]; then
    bin=$UWNR_BIN
elif command -v uwnr >/dev/null; then
    bin=$(command -v uwnr)
elif [ -x target/release/uwnr ]; then
    bin=target/release/uwnr
elif [ -x target/debug/uwnr ]; then
    bin=target/debug/uwnr
else
    die "no uwnr binary: install it (README) or set UWNR_BIN"
fi
[ -x "$bin" ] || die "UWNR_BIN=$bin is not an executable"
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
[ -d "$DATA/inair" ] && [ -d "$DATA/references/u45" ] ||
    skip "the data folder $DATA (inair/, references/u45/) is absent"

# --- Slurm and munge ----------------------------------------------------------------------------
have_slurm() { command -v slurmctld && command -v slurmd && command -v sbatch && command -v munged; } >/dev/null
if ! have_slurm; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing Debian's slurm-wlm and munge"
        apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null 2>&1 ||
            { apt-get update -qq >/dev/null 2>&1 &&
                apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null 2>&1; } ||
            skip "slurm-wlm and munge are not installed and apt-get could not install them"
    fi
    have_slurm || skip "slurm-wlm and munge are not installed (apt-get install slurm-wlm munge)"
fi

W=$(mktemp -d "${TMPDIR:-/tmp}/uwnr-slurm.XXXXXX")
chmod 700 "$W"
pids=()
cleanup() {
    local rc=$?
    set +e
    if [ -n "${SLURM_CONF:-}" ] && [ -f "$SLURM_CONF" ]; then
        # Jobs first, so that no step outlives its slurmd.
        scancel --full --quiet --user="$(id -un)" >/dev/null 2>&1
        for _ in $(seq 1 50); do
            [ -z "$(squeue -h -o %i 2>/dev/null)" ] && break
            sleep 0.2
        done
    fi
    local p
    for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; done
    for p in "${pids[@]}"; do
        for _ in $(seq 1 50); do
            kill -0 "$p" 2>/dev/null || break
            sleep 0.1
        done
        kill -KILL "$p" 2>/dev/null
        wait "$p" 2>/dev/null
    done
    if [ "$rc" != 0 ] && [ -d "$W/log" ]; then
        for f in "$W"/log/*.log "$W"/jobs/*.log; do
            [ -f "$f" ] || continue
            echo "--- last lines of $(basename "$f")" >&2
            tail -n 15 "$f" >&2
        done
    fi
    if [ "${KEEP:-0}" = 1 ]; then say "kept $W"; else rm -rf "$W"; fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
mkdir -p "$W"/{munge,state,spool,run,log,jobs,data/images,data/labels,data/refs}
chmod 700 "$W/munge"

head -c 1024 /dev/urandom >"$W/munge/munge.key"
chmod 400 "$W/munge/munge.key"
munged --foreground --force --key-file="$W/munge/munge.key" --socket="$W/munge/munge.socket" \
    --pid-file="$W/run/munged.pid" --log-file="$W/log/munged.log" \
    --seed-file="$W/munge/munged.seed" >>"$W/log/munged.log" 2>&1 &
pids+=($!)

node=$(hostname -s)
cpus=$(nproc)
user=$(id -un)
export SLURM_CONF=$W/slurm.conf
cat >"$SLURM_CONF" <<EOF
# A one-node cluster for tools/slurm_e2e.sh (Slurm 22.05: no cgroup plugins, so no cgroup.conf).
ClusterName=uwnr-e2e
SlurmctldHost=$node(127.0.0.1)
SlurmUser=$user
SlurmdUser=$user
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
AuthType=auth/munge
CredType=cred/munge
# cred_expire is also how long Slurm holds a requeued job before it may start again (default 120 s).
AuthInfo=socket=$W/munge/munge.socket,cred_expire=10
StateSaveLocation=$W/state
SlurmdSpoolDir=$W/spool
SlurmctldPidFile=$W/run/slurmctld.pid
SlurmdPidFile=$W/run/slurmd.pid
SlurmctldLogFile=$W/log/slurmctld.log
SlurmdLogFile=$W/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
SchedulerParameters=defer_batch
MinJobAge=600
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=4096 State=UNKNOWN
PartitionName=e2e Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

for _ in $(seq 1 50); do [ -S "$W/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$W/munge/munge.socket" ] || die "munged did not start (log: $W/log/munged.log)"
slurmctld -D -f "$SLURM_CONF" >>"$W/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$node" >>"$W/log/slurmd.out" 2>&1 &
pids+=($!)
for i in $(seq 1 150); do
    state=$(sinfo -h -N -o %T 2>/dev/null | head -1 || true)
    [ "$state" = idle ] && break
    [ "$i" = 150 ] && die "the node did not come up (sinfo says '${state:-nothing}')"
    sleep 0.2
done
say "a one-node Slurm $(sinfo -V | awk '{print $2}') is up: node $node, $cpus CPUs ($W)"

# --- inputs: clean photos with YOLO labels, references --------------------------------------------
find "$DATA/inair" -type f \( -iname '*.jpg' -o -iname '*.png' \) | sort | awk -v n="$IMAGES" '
    { all[NR] = $0 } END { step = NR / n; for (i = 0; i < n; i++) print all[int(i * step) + 1] }' |
    while read -r f; do
        name=$(basename "$(dirname "$f")")-$(basename "$f")
        cp "$f" "$W/data/images/$name"
    done
i=0
for f in "$W"/data/images/*; do
    stem=$(basename "${f%.*}")
    # Two boxes of classes 0 and 1 that move with the image's index (YOLO: class cx cy w h).
    awk -v i="$i" 'BEGIN {
        printf "0 %.4f %.4f %.4f %.4f\n", 0.30 + (i % 5) * 0.08, 0.40, 0.25, 0.30
        printf "1 %.4f %.4f %.4f %.4f\n", 0.70, 0.25 + (i % 7) * 0.07, 0.20, 0.22 }' \
        >"$W/data/labels/$stem.txt"
    i=$((i + 1))
done
find "$DATA/references/u45" -type f | sort | awk 'NR % 9 == 1' | while read -r f; do
    cp "$f" "$W/data/refs/$(basename "$(dirname "$f")")-$(basename "$f")"
done
n_images=$(find "$W/data/images" -type f | wc -l)
n_refs=$(find "$W/data/refs" -type f | wc -l)
[ "$n_images" -ge "$SHARDS" ] || die "only $n_images clean images for $SHARDS shards"
planned=$((n_images * PER_IMAGE))
say "$n_images clean images (YOLO labels), $n_refs references, $PER_IMAGE renders each at $SIZE: $planned pairs in $SHARDS shards"

# --- the recipe, as docs/datasets.md gives it ------------------------------------------------------
export PATH="$(dirname "$bin"):$PATH"
export CLEAN=$W/data/images REFS=$W/data/refs OUT=$W/out-slurm PER_IMAGE SHARDS
export UWNR_ARGS="--size $SIZE --seed 7 --yolo $W/data/labels"
cd "$W/jobs"
# The node has $cpus CPUs: one per task, so that the tasks share the node and queue.
jid=$(sbatch --parsable --array=0-$((SHARDS - 1)) --cpus-per-task=1 --mem=1G \
    "$ROOT/examples/slurm/dataset.sbatch")
mid=$(sbatch --parsable --dependency=afterok:"$jid" --mem=1G "$ROOT/examples/slurm/merge.sbatch")
say "submitted array job $jid (tasks 0-$((SHARDS - 1))) and merge job $mid (afterok:$jid)"

job_state() { scontrol -o show job "$1" 2>/dev/null | grep -o 'JobState=[A-Z_]*' | head -1 | cut -d= -f2; }

# Waits until array task $1 runs and has recorded at least 2 pairs; prints that count.
wait_mid_run() {
    local t=$1 manifest=$OUT/manifest.shard-$1-of-$SHARDS.jsonl made state start=$SECONDS
    while :; do
        made=0
        [ -f "$manifest" ] && made=$(wc -l <"$manifest")
        state=$(job_state "${jid}_$t")
        if [ "$made" -ge 2 ]; then
            [ "$state" = RUNNING ] || die "task $t was $state, not running, after $made pairs: too quick to kill (more IMAGES, or a larger SIZE)"
            echo "$made"
            return
        fi
        case $state in COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY)
            die "task $t ended ($state) before it was killed" ;;
        esac
        [ $((SECONDS - start)) -lt "$DEADLINE_S" ] || die "task $t made no pairs in ${DEADLINE_S}s (state ${state:-unknown})"
        sleep 0.1
    done
}

# Checks that the last run in a task's log kept at least $2 pairs; prints that run's first line.
check_resumed() {
    local log=$1 made=$2 runs resumed kept
    runs=$(grep -c 'pairs planned in shard' "$log" || true)
    [ "$runs" -ge 1 ] || die "$(basename "$log") shows no run"
    resumed=$(grep 'pairs planned in shard' "$log" | tail -1)
    kept=$(sed -E 's/.*: ([0-9]+) already done.*/\1/' <<<"$resumed")
    [ "$kept" -ge "$made" ] 2>/dev/null || die "$(basename "$log"): the shard started over: '$resumed'"
    echo "$resumed"
}

# 1. A node dies: Slurm requeues its tasks (dataset.sbatch asks for --requeue). `scontrol requeue`
# does what Slurm does then: the task goes back in the queue under the same job ID, so the merge
# job's afterok dependency still holds. Its uwnr process is sent SIGKILL at once, with no chance to
# finish the pairs in progress, as when the node dies (`scontrol requeue` alone sends SIGTERM first).
killed=$(wait_mid_run "$KILL_TASK") || die "task $KILL_TASK could not be killed mid-run"
pid=$(pgrep -f -- "--output $OUT .*--shard $KILL_TASK/$SHARDS" | head -1 || true)
[ -n "$pid" ] || die "no uwnr process for shard $KILL_TASK/$SHARDS"
scontrol requeue "${jid}_${KILL_TASK}"
kill -KILL "$pid" 2>/dev/null || true
killed=$(wc -l <"$OUT/manifest.shard-$KILL_TASK-of-$SHARDS.jsonl")
say "node death: task $KILL_TASK requeued and its uwnr process sent SIGKILL mid-run, with $killed pairs of its shard recorded"

# 2. A task fails for good (here `scancel`; a time limit or memory alike): the merge job can never
# start. As docs/datasets.md says: run the shard again (it resumes), cancel the stuck merge job and submit
# it again after the rest of the array has ended and the rerun has succeeded.
cancel_task=$(( (KILL_TASK + 1) % SHARDS ))
cancelled=$(wait_mid_run "$cancel_task") || die "task $cancel_task could not be cancelled mid-run"
scancel "${jid}_${cancel_task}"
start=$SECONDS
until [ "$(job_state "${jid}_${cancel_task}")" = CANCELLED ]; do
    [ $((SECONDS - start)) -lt 60 ] || die "task $cancel_task is $(job_state "${jid}_${cancel_task}") after scancel"
    sleep 0.1
done
cancelled=$(wc -l <"$OUT/manifest.shard-$cancel_task-of-$SHARDS.jsonl")
until [ "$(squeue -h -j "$mid" -o %r 2>/dev/null)" = DependencyNeverSatisfied ]; do
    [ $((SECONDS - start)) -lt 60 ] || die "the merge job is $(job_state "$mid") ($(squeue -h -j "$mid" -o %r)), not waiting forever, after a task was cancelled"
    sleep 0.2
done
rid=$(sbatch --parsable --array="$cancel_task" --cpus-per-task=1 --mem=1G "$ROOT/examples/slurm/dataset.sbatch")
scancel "$mid"
mid=$(sbatch --parsable --dependency=afterany:"$jid",afterok:"$rid" --mem=1G "$ROOT/examples/slurm/merge.sbatch")
say "failure: task $cancel_task cancelled mid-run with $cancelled pairs recorded; the merge job waited forever (DependencyNeverSatisfied); shard $cancel_task resubmitted as job $rid, merge as job $mid (afterany:$jid,afterok:$rid)"

start=$SECONDS
while :; do
    state=$(job_state "$mid")
    case $state in
    COMPLETED) break ;;
    FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY) die "the merge job ended $state" ;;
    esac
    reason=$(squeue -h -j "$mid" -o %r 2>/dev/null || true)
    [ "$reason" = DependencyNeverSatisfied ] && die "the merge job's dependency can never be satisfied"
    [ $((SECONDS - start)) -lt "$DEADLINE_S" ] || die "the merge job did not finish in ${DEADLINE_S}s (state ${state:-unknown}, ${reason:-})"
    sleep 0.5
done

# Each interrupted shard's last run kept what the interrupted run had recorded.
task_log=$W/jobs/uwnr-dataset-${jid}_${KILL_TASK}.log
[ "$(grep -c 'pairs planned in shard' "$task_log")" -ge 2 ] || die "task $KILL_TASK's log shows no restart"
resumed=$(check_resumed "$task_log" "$killed") || die "task $KILL_TASK did not resume"
say "task $KILL_TASK resumed ($(grep -o 'restart [0-9]*' "$task_log" | tail -1)): $resumed"
resumed=$(check_resumed "$W/jobs/uwnr-dataset-${rid}_${cancel_task}.log" "$cancelled") || die "shard $cancel_task did not resume"
say "shard $cancel_task resumed as job $rid: $resumed"
for t in $(seq 0 $((SHARDS - 1))); do
    s=$(job_state "${jid}_$t")
    want=COMPLETED
    [ "$t" = "$cancel_task" ] && want=CANCELLED
    [ "$s" = "$want" ] || die "array task $t is $s, not $want"
done
[ "$(job_state "${rid}_${cancel_task}")" = COMPLETED ] || die "the rerun of shard $cancel_task is $(job_state "${rid}_${cancel_task}")"
merge_log=$W/jobs/uwnr-merge-$mid.log
grep -q '^verify: OK' "$merge_log" || die "the merge job's verify did not print OK"
say "merge job: $(grep -h '^merged\|^merge took\|^verify:' "$merge_log" | paste -sd ';' -)"

# --- the same command on one machine --------------------------------------------------------------
read -r -a extra <<<"$UWNR_ARGS"
"$bin" dataset --clean "$CLEAN" --references "$REFS" --output "$W/out-single" \
    --per-image "$PER_IMAGE" --jobs "$cpus" "${extra[@]}" >"$W/jobs/single.log" 2>&1 ||
    die "the single-machine run failed (see $W/jobs/single.log)"
say "single machine: $(grep '^dataset:' "$W/jobs/single.log")"

files=$(cd "$W/out-single" && find . -type f | wc -l)
labels=$(find "$W/out-single/labels" -type f 2>/dev/null | wc -l)
if differences=$(diff -r -q "$W/out-slurm" "$W/out-single" 2>&1); then
    echo "slurm_e2e: byte-identical: the merged Slurm run ($SHARDS shards; task $KILL_TASK killed and requeued, task $cancel_task cancelled and resubmitted, both resumed) equals the single-machine run, $files files ($planned pairs, $labels label files), in ${SECONDS} s"
else
    echo "$differences" | head -20 >&2
    echo "slurm_e2e: DIFFERENT: the merged Slurm run and the single-machine run differ in $(echo "$differences" | wc -l) place(s): $(echo "$differences" | head -3 | paste -sd ';' -)"
    exit 1
fi

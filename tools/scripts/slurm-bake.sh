#!/usr/bin/env bash
# slurm-bake.sh — a sharded bake on a real Slurm cluster, with one shard killed mid-sample.
#
# Usage:  tools/scripts/slurm-bake.sh [--lensmap PATH] [--keep]
#
# Starts a one-node Slurm cluster on this machine (munged, slurmctld and slurmd from Debian's
# `munge` and `slurm-wlm`, installed with apt-get when missing; every configuration file, the
# MUNGE key, the state, spool and logs in a fresh temporary folder, nothing written under /etc),
# then runs docs/baking.md's Slurm recipe on glass-sphere at tools/tests/bake.rs's tiny settings:
#
#   1. an array job of 4 shards (`lensmap bake --shard K/4 --resume`), 12 viewpoint samples, so
#      every shard bakes 3; and the merge as a job depending on every shard's success;
#   2. shard 1's `lensmap` is killed with SIGKILL once its first sample (0) is staged, while its
#      second (4) is in flight: the task ends FAILED and the merge's dependency can never be met;
#   3. the recipe brings it back: `scontrol requeue` of the failed task, then the merge's
#      dependency named again task by task (`scontrol update … Dependency=afterok:A_1:…:A_4`);
#   4. the requeued task resumes: its JSON must say it took sample 0 from the staging directory
#      and baked 4 and 8 only;
#   5. the merge runs, and its bake must be byte-identical (cmp of every file, and the same file
#      list) to a one-process bake of the same 12 samples.
#
# It prints a transcript (jobs and their states from scontrol and the job-completion log, the
# kill, the requeue, the merge, the comparison, the wall time) and exits non-zero on any
# mismatch or timeout. The daemons are stopped and the folder removed on exit, failure included
# (--keep keeps the folder and says where). Needs root (slurmd runs jobs as their user) and
# 2 CPUs; the requeue delay is shortened to 11 s (`AuthInfo=cred_expire=10`; Slurm's default
# holds a requeued job for 121 s).
#
# --lensmap PATH  the binary to run (default: target/release/lensmap, built first with
#                 `cargo build --release --bin lensmap`, a no-op when it is current).
set -euo pipefail

repo=$(cd "$(dirname "$0")/../.." && pwd)
lensmap=
keep=0
while [ $# -gt 0 ]; do
    case $1 in
        --lensmap) lensmap=${2:?--lensmap needs a path}; shift 2 ;;
        --keep) keep=1; shift ;;
        -h | --help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "slurm-bake.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done

if [ "$(id -u)" != 0 ]; then
    echo "slurm-bake.sh: needs root: slurmd runs the jobs as their user (SlurmdUser=root)" >&2
    exit 2
fi

# The packages, once per machine (excluded from the measured time).
missing=()
for package in slurm-wlm munge jq; do
    dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing: ${missing[*]}"
    apt-get update -qq
    # The packages' init scripts cannot start anything here (no init system); this script starts
    # the daemons itself, from its own configuration.
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

if [ -z "$lensmap" ]; then
    (cd "$repo" && CARGO_INCREMENTAL=${CARGO_INCREMENTAL:-0} cargo build --release --bin lensmap)
    lensmap=$repo/target/release/lensmap
fi
lensmap=$(realpath "$lensmap")
[ -x "$lensmap" ] || { echo "slurm-bake.sh: $lensmap is not an executable" >&2; exit 2; }

start=$SECONDS
shards=4
killed=1 # the shard whose process is killed
samples=0..12
# tools/tests/bake.rs's TINY settings.
tiny=(--scene glass-sphere --samples "$samples" --width 48 --height 36 --supersampling 1
    --em-size 16 --layers 2 --multi-view 2 --no-judge)

# The folder: munged refuses a socket in a folder others cannot enter, so 0755, not mktemp's 0700.
root=$(mktemp -d /tmp/lensmap-slurm.XXXXXX)
chmod 0755 "$root"
mkdir -p "$root/munge" "$root/state" "$root/spool" "$root/log" "$root/work/bakes"
work=$root/work
bakes=$work/bakes
export SLURM_CONF=$root/slurm.conf
daemons=() # pids of the daemons this script started, stopped in reverse order
jobs_submitted=()
status=1

say() { printf '%s\n' "$*"; }
step() { printf '[%3ds] %s\n' $((SECONDS - start)) "$*"; }
fail() {
    step "FAILED: $*"
    exit 1
}

cleanup() {
    local code=$?
    set +e
    if [ ${#jobs_submitted[@]} -gt 0 ] && [ -n "$(squeue -h -o %i 2>/dev/null)" ]; then
        scancel "${jobs_submitted[@]}" 2>/dev/null
        for _ in $(seq 1 40); do
            [ -z "$(squeue -h -o %i 2>/dev/null)" ] && break
            sleep 0.5
        done
    fi
    if [ "$code" != 0 ] || [ "$status" != 0 ]; then
        for log in slurmctld.log slurmd.log munged.log; do
            [ -s "$root/log/$log" ] && { say "--- last lines of $log"; tail -n 15 "$root/log/$log"; }
        done
    fi
    local i
    for ((i = ${#daemons[@]} - 1; i >= 0; i--)); do
        kill -TERM "${daemons[i]}" 2>/dev/null
    done
    for ((i = ${#daemons[@]} - 1; i >= 0; i--)); do
        for _ in $(seq 1 40); do
            kill -0 "${daemons[i]}" 2>/dev/null || break
            sleep 0.25
        done
        kill -KILL "${daemons[i]}" 2>/dev/null
        wait "${daemons[i]}" 2>/dev/null
    done
    if [ "$keep" = 1 ]; then
        say "kept: $root"
    else
        rm -rf "$root"
    fi
    exit "$code"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# A free TCP port other than $1: one that nothing listens on (/proc/net/tcp{,6}: the local
# address's port in hex after its last colon, state 0A is LISTEN).
free_port() {
    local port
    while :; do
        port=$((20000 + RANDOM % 30000))
        [ "$port" = "${1:-}" ] && continue
        if ! awk -v port="$(printf '%04X' "$port")" '
                $4 == "0A" && toupper(substr($2, length($2) - 3)) == port { found = 1 }
                END { exit !found }' /proc/net/tcp /proc/net/tcp6 2>/dev/null; then
            echo "$port"
            return
        fi
    done
}

# --- MUNGE: its own key and socket.
mungekey --create --keyfile="$root/munge/munge.key"
munged --foreground --key-file="$root/munge/munge.key" --socket="$root/munge/munge.socket" \
    --pid-file="$root/munge/munged.pid" --log-file="$root/log/munged.log" \
    --seed-file="$root/munge/munged.seed" >"$root/log/munged.out" 2>&1 &
daemons+=($!)
for _ in $(seq 1 40); do [ -S "$root/munge/munge.socket" ] && break; sleep 0.25; done
munge -S "$root/munge/munge.socket" -n | unmunge -S "$root/munge/munge.socket" >/dev/null ||
    fail "munged does not answer on $root/munge/munge.socket"

# --- Slurm: one node with 2 CPUs, this machine. No systemd or cgroups here: processes are
# tracked through /proc, tasks are not bound, nothing is accounted but the completion log.
node=$(hostname -s)
controller_port=$(free_port)
cat >"$SLURM_CONF" <<EOF
ClusterName=lensmap
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$controller_port
SlurmdPort=$(free_port "$controller_port")
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$root/munge/munge.socket,cred_expire=10
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$root/state
SlurmdSpoolDir=$root/spool
SlurmctldPidFile=$root/slurmctld.pid
SlurmdPidFile=$root/slurmd.pid
SlurmctldLogFile=$root/log/slurmctld.log
SlurmdLogFile=$root/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$root/log/jobcomp.txt
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=2,bf_interval=2
# A site that does not requeue by default: the recipe asks for it (sbatch --requeue).
JobRequeue=0
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
NodeName=$node NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=main Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -f "$SLURM_CONF" >"$root/log/slurmctld.out" 2>&1 &
daemons+=($!)
slurmd -D -f "$SLURM_CONF" >"$root/log/slurmd.out" 2>&1 &
daemons+=($!)
for _ in $(seq 1 60); do
    [ "$(sinfo -h -o %T 2>/dev/null)" = idle ] && break
    sleep 0.5
done
[ "$(sinfo -h -o %T 2>/dev/null)" = idle ] || fail "the node did not come up idle: $(sinfo 2>&1)"
version=$(sinfo -V)
step "cluster up: $version, node $node with 2 CPUs, config $SLURM_CONF"

# --- The job scripts: docs/baking.md's recipe. The shard's summary goes to one JSON file per
# attempt (SLURM_RESTART_COUNT counts requeues), which the checks below read.
cat >"$work/bake.sh" <<EOF
#!/bin/sh
#SBATCH --array=1-$shards --cpus-per-task=1 --requeue --output=bakes/slurm-%A_%a.out
'$lensmap' bake ${tiny[*]} \\
    --shard \${SLURM_ARRAY_TASK_ID}/$shards --resume --out bakes/shard-\${SLURM_ARRAY_TASK_ID} \\
    --json >bakes/shard-\${SLURM_ARRAY_TASK_ID}.attempt-\${SLURM_RESTART_COUNT:-0}.json
EOF
cat >"$work/merge.sh" <<EOF
#!/bin/bash
#SBATCH --output=bakes/merge-%j.out
'$lensmap' bake --merge bakes/shard-{1..$shards} --out bakes/merged
EOF

job_field() { # job_field JOB FIELD: one field of `scontrol show job`
    scontrol show job -o "$1" | tr ' ' '\n' | sed -n "s/^$2=//p" | head -1
}
wait_for() { # wait_for SECONDS WHAT COMMAND...: poll COMMAND every 0.1 s
    local limit=$1 what=$2 until
    shift 2
    until=$((SECONDS + limit))
    until "$@"; do
        [ $SECONDS -lt $until ] || fail "timed out after ${limit}s waiting for $what"
        sleep 0.1
    done
}

cd "$work"
array=$(sbatch --parsable bake.sh)
jobs_submitted+=("$array")
merge=$(sbatch --parsable --dependency=afterok:"$array" merge.sh)
jobs_submitted+=("$merge")
step "submitted: array job $array (tasks 1-$shards), merge job $merge (--dependency=afterok:$array)"

# --- The kill: shard 1's first sample staged, the second in flight.
staging=$bakes/.shard-$killed.baking
# The victim's pid first (the task's lensmap, once started), so that nothing but a file test
# stands between seeing its first sample staged and the kill; polled every 20 ms: a sample takes
# about half a second here.
victim=
until [ -n "$victim" ]; do
    [ $((SECONDS - start)) -lt 300 ] || fail "no lensmap process among job ${array}_$killed's (scontrol listpids)"
    # listpids takes the task's own job id, not ARRAY_TASK.
    for pid in $(scontrol listpids "$(job_field "${array}_$killed" JobId)" 2>/dev/null | awk 'NR > 1 { print $1 }'); do
        [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = lensmap ] && victim=$pid
    done
    [ -n "$victim" ] || sleep 0.02
done
until [ -e "$staging/sample-000.json" ]; do
    [ $((SECONDS - start)) -lt 300 ] || fail "timed out waiting for shard $killed's first sample"
    sleep 0.02
done
kill -KILL "$victim"
staged=$(cd "$staging" && ls sample-*.json | tr '\n' ' ')
step "kill -9 $victim (job ${array}_$killed's lensmap) with staged: $staged"
[ "$staged" = "sample-000.json " ] || fail "the kill did not land while sample 4 was in flight"
# A lensmap that locks its --out leaves its lock file behind; the requeued task must take it over.
lock=$bakes/.shard-$killed.lock
[ -e "$lock" ] && step "left behind by the killed process: $(basename "$lock"): $(head -c 200 "$lock")"

task_failed() { [ "$(job_field "${array}_$killed" JobState)" = FAILED ]; }
wait_for 60 "job ${array}_$killed to fail" task_failed
step "job ${array}_$killed: JobState=FAILED ExitCode=$(job_field "${array}_$killed" ExitCode)"
merge_blocked() { [ "$(job_field "$merge" Reason)" = DependencyNeverSatisfied ]; }
wait_for 60 "the merge's dependency to fail" merge_blocked
step "job $merge (merge): Reason=DependencyNeverSatisfied Dependency=$(job_field "$merge" Dependency)"

# --- The recipe: requeue the task, then name the merge's dependency again, task by task (the
# array as a whole keeps its failure: afterok:$array would stay unsatisfiable).
scontrol requeue "${array}_$killed"
tasks=$(seq -f "${array}_%g" -s : 1 $shards)
scontrol update JobId="$merge" Dependency="afterok:$tasks"
step "scontrol requeue ${array}_$killed; scontrol update JobId=$merge Dependency=afterok:$tasks"
step "job ${array}_$killed: JobState=$(job_field "${array}_$killed" JobState) Reason=$(job_field "${array}_$killed" Reason) EligibleTime=$(job_field "${array}_$killed" EligibleTime)"

merge_done() {
    case $(job_field "$merge" JobState) in
        COMPLETED) return 0 ;;
        FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY)
            fail "the merge job ended $(job_field "$merge" JobState): $(cat "$bakes/merge-$merge.out")" ;;
        *) return 1 ;;
    esac
}
wait_for 300 "the merge job" merge_done
step "job $merge (merge): COMPLETED: $(cat "$bakes/merge-$merge.out")"

say "--- jobs (scontrol show job)"
for job in $(seq 1 $shards | sed "s/^/${array}_/") "$merge"; do
    printf '  %-8s %-10s ExitCode=%-5s Restarts=%s Start=%s End=%s\n' "$job" \
        "$(job_field "$job" JobState)" "$(job_field "$job" ExitCode)" \
        "$(job_field "$job" Restarts)" "$(job_field "$job" StartTime)" "$(job_field "$job" EndTime)"
done
say "--- the job-completion log, in order (every end of a job, the killed attempt's included)"
awk '{ delete f; for (i = 1; i <= NF; i++) { split($i, kv, "="); f[kv[1]] = kv[2] }
       id = f["ArrayTaskId"] == "" ? f["JobId"] : f["ArrayJobId"] "_" f["ArrayTaskId"]
       printf "  %-8s %-10s ExitCode=%-5s %s .. %s\n", id, f["JobState"], f["ExitCode"], f["StartTime"], f["EndTime"] }' \
    "$root/log/jobcomp.txt"

# --- The resumed shard: sample 0 taken from the staging directory, 4 and 8 baked.
report=$bakes/shard-$killed.attempt-1.json
[ -s "$report" ] || fail "no JSON from the requeued attempt ($report)"
resumed=$(jq -c '.summary.resumed' "$report")
baked=$(jq -c '.summary.baked' "$report")
step "requeued shard $killed: resumed $resumed, baked $baked"
[ "$resumed" = "[0]" ] && [ "$baked" = "[4,8]" ] ||
    fail "the requeued shard should resume [0] and bake [4,8]"
for k in $(seq 1 $shards); do
    [ "$k" = "$killed" ] && continue
    [ "$(jq -c '.summary.resumed' "$bakes/shard-$k.attempt-0.json")" = "[]" ] ||
        fail "shard $k resumed samples it never staged"
done

# --- One process, the same samples; then every file compared.
"$lensmap" bake "${tiny[@]}" --out "$work/whole" -q
step "one-process bake of $samples done"
list() { (cd "$1" && find . -type f | sort); }
if ! diff <(list "$bakes/merged") <(list "$work/whole") >/dev/null; then
    diff <(list "$bakes/merged") <(list "$work/whole") || true
    fail "the merged bake and the one-process bake hold different files"
fi
files=0
while read -r file; do
    cmp "$bakes/merged/$file" "$work/whole/$file" || fail "$file differs"
    files=$((files + 1))
done < <(list "$work/whole")
step "cmp: all $files files of the merged bake are byte-identical to the one-process bake"
say "samples per shard: $(for k in $(seq 1 $shards); do printf '%s=%s ' "$k" \
    "$(jq -c '.provenance.samples' "$bakes/shard-$k/manifest.json")"; done)"
status=0
step "PASS (wall time $((SECONDS - start))s from cluster start, package install and build excluded; $("$lensmap" --version 2>/dev/null | head -1))"

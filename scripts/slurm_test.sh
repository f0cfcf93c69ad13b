#!/usr/bin/env bash
# A sweep on a real Slurm: starts a one-node cluster on localhost from Debian's packages
# (munge + slurmctld + slurmd, a generated slurm.conf, all state in a temporary folder),
# submits experiments/sweeps/tiny.toml as a job array with `ifslab sweep --slurm --submit`,
# cancels one array task mid-run (scancel), resubmits, and checks that the merged results
# have every run once, the cancelled one resumed, and equal a local run of the same sweep
# (summaries bit for bit, wall-time columns aside). Cleans up after itself.
#
#   scripts/slurm_test.sh [path/to/ifslab]      # default: target/ci/ifslab (built if missing)
#
# Exit status: 0 passed, 77 skipped (Slurm cannot be installed or started here; the reason
# is printed), anything else failed.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$(pwd)"
skip() { echo "SLURM TEST SKIPPED: $*" >&2; exit 77; }
fail() { echo "SLURM TEST FAILED: $*" >&2; exit 1; }

IFSLAB="${1:-$root/target/ci/ifslab}"
if [ ! -x "$IFSLAB" ]; then
  cargo build --profile ci -p ifslab-experiments
fi
IFSLAB="$(cd "$(dirname "$IFSLAB")" && pwd)/$(basename "$IFSLAB")"

if ! command -v slurmctld >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
  command -v apt-get >/dev/null 2>&1 || skip "slurm-wlm and munge are not installed and there is no apt-get"
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo -n"
  { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq slurm-wlm munge >/dev/null; } \
    || skip "apt-get install slurm-wlm munge failed"
fi
[ "$(id -u)" = 0 ] || skip "slurmd must run as root to start jobs (run the tests as root, as CI does)"
command -v python3 >/dev/null 2>&1 || fail "python3 is needed to compare the tables"

tmp="$(mktemp -d /tmp/ifslab-slurm.XXXXXX)"
pids=()
cleanup() {
  local p
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
  if [ -n "${KEEP_SLURM_TMP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT

# munge: its own key, socket and logs in the temporary folder.
mkdir -p "$tmp/munge" "$tmp/state" "$tmp/spool"
chmod 700 "$tmp/munge"
head -c 1024 /dev/urandom > "$tmp/munge/munge.key"
chmod 400 "$tmp/munge/munge.key"
socket="$tmp/munge/munge.socket.2"
munged --force --foreground --key-file="$tmp/munge/munge.key" --socket="$socket" \
  --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/munge/munged.log" \
  --seed-file="$tmp/munge/munged.seed" 2>"$tmp/munge/stderr" &
pids+=($!)
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
[ -S "$socket" ] || skip "munged did not start: $(cat "$tmp/munge/stderr" "$tmp/munge/munged.log" 2>/dev/null | tail -3)"

# A one-node cluster with no cgroups (containers have none to give): linuxproc process
# tracking, no task plugin, no accounting. Free ports, so that nothing else is disturbed.
host="$(hostname -s)"
port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
cpus="$(nproc)"
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
export SLURM_CONF="$tmp/slurm.conf"
cat > "$SLURM_CONF" <<CONF
ClusterName=ifslabtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$(port)
SlurmdPort=$(port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
SlurmdTimeout=60
InactiveLimit=0
KillWait=5
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -D -i -f "$SLURM_CONF" 2>"$tmp/slurmctld.stderr" &
pids+=($!)
slurmd -D -f "$SLURM_CONF" 2>"$tmp/slurmd.stderr" &
pids+=($!)
up=""
for _ in $(seq 100); do
  if sinfo -h -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then up=1; break; fi
  sleep 0.2
done
[ -n "$up" ] || skip "the one-node cluster did not come up: $(tail -3 "$tmp/slurmctld.log" "$tmp/slurmd.log" "$tmp"/*.stderr 2>/dev/null)"
echo "slurm: one node ($cpus CPUs) up in $tmp"

sweep="$root/experiments/sweeps/tiny.toml"
out="$tmp/cluster"
wait_job() {
  local job=$1
  for _ in $(seq 1200); do
    [ -z "$(squeue -h -j "$job" 2>/dev/null)" ] && return 0
    sleep 0.5
  done
  fail "job $job did not finish in 10 minutes"
}
submit() {
  local line
  line="$("$IFSLAB" sweep "$sweep" -o "$out" --slurm --submit | grep '^submitted job')" || fail "submission failed"
  echo "$line" | awk '{print $3}' | tr -d ';'
}

# 1. Submit; cancel one array task once its run has a checkpoint and is not finished.
job="$(submit)"
echo "slurm: submitted job $job"
victim=""
for _ in $(seq 1200); do
  for ck in "$out"/runs/.*.partial/checkpoint.json; do
    [ -f "$ck" ] || continue
    id="$(basename "$(dirname "$ck")" .partial)"; id="${id#.}"
    victim="$(python3 -c 'import json,sys; p=json.load(open(sys.argv[1])); print([i for i,r in enumerate(p["runs"]) if r["id"]==sys.argv[2]][0])' "$out/sweep.json" "$id")"
    break 2
  done
  sleep 0.05
done
[ -n "$victim" ] || fail "no run wrote a checkpoint"
scancel "${job}_${victim}"
echo "slurm: cancelled array task ${job}_${victim} (run $id) mid-run"
wait_job "$job"
[ -f "$out/runs/$id/run.json" ] && fail "the cancelled run $id finished anyway"
[ -d "$out/runs/.$id.partial" ] || fail "the cancelled run left no partial folder"
"$IFSLAB" collect "$out" >/dev/null
python3 - "$out/report/results.json" "$id" <<'PY' || fail "the collected table after the cancel is wrong"
import json, sys
t = json.load(open(sys.argv[1]))
states = {r["id"]: r["status"] for r in t["runs"]}
assert states[sys.argv[2]] == "interrupted", states
assert sum(s == "finished" for s in states.values()) == len(states) - 1, states
PY
before="$(cd "$out/runs" && for d in */; do [ "$d" = "$id/" ] || sha256sum "$d/summary.json" "$d/run.json"; done)"

# 2. Resubmit: only the cancelled run is done again, from its checkpoint.
job="$(submit)"
echo "slurm: resubmitted as job $job"
wait_job "$job"
after="$(cd "$out/runs" && for d in */; do [ "$d" = "$id/" ] || sha256sum "$d/summary.json" "$d/run.json"; done)"
[ "$before" = "$after" ] || fail "the resubmission touched finished runs"
grep -q '"resumed": true' "$out/runs/$id/run.json" || fail "the cancelled run was not resumed from its checkpoint"
"$IFSLAB" collect "$out" >/dev/null

# 3. The same sweep locally; the merged tables agree.
"$IFSLAB" sweep "$sweep" -o "$tmp/local" --jobs 2 >/dev/null
"$IFSLAB" collect "$tmp/local" >/dev/null
python3 - "$out" "$tmp/local" <<'PY' || fail "the cluster's table differs from the local run's"
import json, os, sys
wall = {"seconds", "run_seconds", "resumed", "threads"}
def table(d):
    t = json.load(open(os.path.join(d, "report", "results.json")))
    rows = []
    for r in t["runs"]:
        r = {k: v for k, v in r.items() if k not in wall}
        r["summary"] = {k: v for k, v in r["summary"].items() if k not in wall}
        rows.append(r)
    return t["axes"], rows
cluster, local = table(sys.argv[1]), table(sys.argv[2])
runs = cluster[1]
assert all(r["status"] == "finished" for r in runs), runs
ids = [r["id"] for r in runs]
assert len(ids) == len(set(ids)), "a run is duplicated"
folders = sorted(n for n in os.listdir(os.path.join(sys.argv[1], "runs")) if not n.startswith("."))
assert folders == sorted(ids), (folders, ids)
partials = [n for n in os.listdir(os.path.join(sys.argv[1], "runs")) if n.endswith(".partial")]
assert not partials, partials
assert cluster == local, "cluster and local tables differ"
print(f"slurm: {len(runs)} runs, none lost or duplicated; the table equals the local run's")
PY
echo "SLURM TEST PASSED"

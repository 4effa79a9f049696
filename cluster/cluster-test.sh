#!/usr/bin/env bash
# `make cluster-test`: a three-node SLURM cluster on this machine, the smoke DAG through
# profiles/slurm in a fresh clone, and the proof that it gives what a local run gives
# (docs/cluster.md, "The local cluster").
#
#  1. installs slurmctld, slurmd, slurm-client and munge from Debian if missing (needs root);
#  2. makes NODES (3) nodes: each a network namespace with its own address on a private bridge
#     (ESNAP_NET.11, .12, ...; the controller at ESNAP_NET.1) and, for its slurmd, its own hostname
#     (a UTS namespace), so that jobs land on different nodes that share this file system; writes
#     their slurm.conf (proctrack/linuxproc, task/none, no accounting; each node this machine's CPUs
#     and an equal share of its memory) and a munge key into a scratch folder;
#  3. starts munged, slurmctld and a slurmd per node (no systemd); on exit, whatever happens (trap),
#     stops them by pid, removes the namespaces and the bridge, and fails if any of them is left;
#  4. clones the repository's HEAD, runs `snakemake --profile profiles/slurm --config budget=smoke`,
#     cancels one running job with scancel, checks that it left no provenance record, reruns
#     (--rerun-incomplete, in the profile) and checks that the job ran again and recorded its host;
#     checks that the provenance records name every node, and only the nodes, as their host;
#  5. runs the same DAG locally (`--cores 2`) in a second clone and compares every claims table:
#     they must be identical, byte for byte.
# Prints the wall time and the number of jobs submitted to SLURM. Exit status 0 only when all holds.
#
# Environment: VENV (default .venv, with `.[cluster]` installed), KEEP=1 keeps the scratch folder,
# NODES (default 3), ESNAP_NET (default 10.77.0: the bridge's /24, which must be free here).
set -euo pipefail

REPO=$(git rev-parse --show-toplevel)
VENV=$(cd "$REPO" && realpath "${VENV:-.venv}")
START=$SECONDS
NICE=(nice -n 5)
PKGS=(slurmctld slurmd slurm-client munge)
NODES=${NODES:-3}
NET=${ESNAP_NET:-10.77.0}
BRIDGE=esnapbr0
NODE_NAMES=()
for i in $(seq "$NODES"); do NODE_NAMES+=("esnap-n$i"); done
CLAIMS=(characterize dynamics policy ablation)

say() { echo "cluster-test: $*"; }
die() { echo "cluster-test: error: $*" >&2; exit 1; }

[ -x "$VENV/bin/snakemake" ] || die "$VENV/bin/snakemake missing (make install, or VENV=...)"
"$VENV/bin/python" -c "import snakemake_executor_plugin_slurm" 2>/dev/null ||
    die "snakemake-executor-plugin-slurm is not installed in $VENV (pip install -e .[cluster])"

# --- 1. packages --------------------------------------------------------------------------------
SUDO=()
[ "$(id -u)" = 0 ] || SUDO=(sudo)
missing=()
for p in "${PKGS[@]}"; do
    dpkg-query -W -f '${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    say "installing ${missing[*]} (apt-get)"
    # Another apt may hold the dpkg lock: wait for it (Lock::Timeout), and retry a few times.
    for try in 1 2 3 4 5 6; do
        if "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=300 update -qq &&
           "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=300 \
               install -y -q --no-install-recommends "${missing[@]}"; then
            break
        fi
        [ "$try" = 6 ] && die "apt-get install ${missing[*]} failed"
        say "apt-get failed (lock held by another apt?), retrying in 20 s"; sleep 20
    done
fi
[ "$(id -u)" = 0 ] || die "the daemons run as root here (SlurmUser=root); run as root"
# One local cluster at a time on a machine (ports 6817/6818, /etc/slurm/slurm.conf): a second
# `make cluster-test` (another CI run) waits here.
exec 9> /tmp/esnap-cluster-test.lock
flock 9

# --- 2. configuration ---------------------------------------------------------------------------
W=$(mktemp -d /tmp/esnap-cluster.XXXXXX)
chmod 700 "$W"
mkdir -p "$W/state" "$W/spool"
PIDS=()
stop() {  # a daemon by its pid file: TERM, then up to 10 s for it to exit, then KILL
    local pid
    [ -s "$1" ] || return 0
    pid=$(cat "$1")
    kill "$pid" 2>/dev/null || return 0
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || return 0; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
}
cleanup() {
    local rc=$? left=() f n
    for f in "$W"/slurmd.*.pid "$W/slurmctld.pid" "$W/munged.pid"; do stop "$f"; done
    for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done
    # A namespace goes once its last process has: the daemons are stopped first.
    for n in "${NODE_NAMES[@]}"; do ip netns del "$n" 2>/dev/null || true; done
    ip link del "$BRIDGE" 2>/dev/null || true
    # A veth pair goes with its namespace, but the kernel removes it a moment later (a check at
    # once once saw two still there): delete the host ends, and give the kernel up to 5 s.
    for n in $(ip -o link show | grep -o 'esnap[a-z0-9]*' | sort -u); do ip link del "$n" 2>/dev/null || true; done
    for _ in $(seq 50); do ip -o link show | grep -q 'esnap' || break; sleep 0.1; done
    [ "$(readlink /etc/slurm/slurm.conf 2>/dev/null)" = "$W/slurm.conf" ] && rm -f /etc/slurm/slurm.conf
    # Nothing this test made may outlive it: daemons, namespaces, the bridge and its links.
    for f in "$W"/slurmd.*.pid "$W/slurmctld.pid" "$W/munged.pid"; do
        if [ -s "$f" ] && kill -0 "$(cat "$f")" 2>/dev/null; then left+=("$(basename "$f" .pid)"); fi
    done
    for n in "${NODE_NAMES[@]}"; do
        if ip netns list | grep -qw "$n"; then left+=("namespace $n"); fi
    done
    for n in $(ip -o link show | grep -o 'esnap[a-z0-9]*' | sort -u); do left+=("link $n"); done
    if [ ${#left[@]} -gt 0 ]; then
        echo "cluster-test: error: left behind: ${left[*]}" >&2
        rc=1
    else
        say "cleaned up: munged, slurmctld and ${#NODE_NAMES[@]} slurmd stopped, namespaces and bridge removed"
    fi
    if [ "${KEEP:-0}" = 1 ] || [ $rc != 0 ]; then say "scratch folder kept: $W"; else rm -rf "$W"; fi
    exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

HOST=$(hostname -s)
mungekey --create --keyfile="$W/munge.key" --force
# Each node: this machine's CPUs (a job asking for 2 threads must fit on one) and an equal share of
# its memory. The nodes share the real cores, so the run is no faster than one node: it shows where
# jobs land, not speed.
CPUS=$(slurmd -C | sed -n 's/^NodeName=.* CPUs=\([0-9]*\) .*/\1/p' | head -1)
MEM=$(slurmd -C | sed -n 's/^NodeName=.* RealMemory=\([0-9]*\).*/\1/p' | head -1)
[ -n "$CPUS" ] && [ -n "$MEM" ] || die "slurmd -C gave no CPUs and RealMemory"
if ip link show "$BRIDGE" > /dev/null 2>&1; then die "a bridge $BRIDGE exists (another cluster test?)"; fi
if ip -4 -o addr | grep -q " $NET\."; then die "$NET.0/24 is in use here: set ESNAP_NET to a free /24"; fi
ip link add "$BRIDGE" type bridge
ip addr add "$NET.1/24" dev "$BRIDGE"
ip link set "$BRIDGE" up
NODE_LINES=""
for i in $(seq "$NODES"); do
    n=${NODE_NAMES[$((i - 1))]}
    ip netns add "$n"
    ip link add "esnapv$i" type veth peer name eth0 netns "$n"
    ip link set "esnapv$i" master "$BRIDGE" up
    ip -n "$n" addr add "$NET.$((10 + i))/24" dev eth0
    ip -n "$n" link set eth0 up
    ip -n "$n" link set lo up
    NODE_LINES+="NodeName=$n NodeAddr=$NET.$((10 + i))"$'\n'
done
cat > "$W/slurm.conf" <<EOF
ClusterName=esnaptest
SlurmctldHost=$HOST($NET.1)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$W/munge.socket
SlurmUser=root
SlurmdUser=root
SlurmctldPort=${SLURMCTLD_PORT:-6817}
SlurmdPort=${SLURMD_PORT:-6818}
StateSaveLocation=$W/state
SlurmdSpoolDir=$W/spool/%n
SlurmctldPidFile=$W/slurmctld.pid
SlurmdPidFile=$W/slurmd.%n.pid
SlurmctldLogFile=$W/slurmctld.log
SlurmdLogFile=$W/slurmd.%n.log
# No cgroups in a container: processes tracked by parent pid, no task binding.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
# No accounting database: job states come from squeue (profiles/slurm: slurm-status-command).
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
# Finished jobs stay visible to squeue this long (the plugin needs >= 2 min to trust squeue).
MinJobAge=300
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
NodeName=DEFAULT CPUs=$CPUS RealMemory=$((MEM / NODES)) State=UNKNOWN
# LLN: each job to the least loaded node, so that every node gets work even when few jobs run.
${NODE_LINES}PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP LLN=YES
EOF
# At the default path: the job-step plugin starts each job's srun without SLURM_* variables, so
# SLURM_CONF would not reach it. A slurm.conf that is not ours is never touched.
ETC=/etc/slurm/slurm.conf
if [ -e "$ETC" ] || [ -L "$ETC" ]; then
    readlink "$ETC" | grep -q '^/tmp/esnap-cluster\.' ||
        die "$ETC exists (a real cluster's?): run this on a machine without one"
    rm -f "$ETC"  # left by an earlier run that was killed
fi
mkdir -p /etc/slurm
ln -s "$W/slurm.conf" "$ETC"
export SLURM_CONF="$ETC"

# --- 3. daemons ---------------------------------------------------------------------------------
munged --force --socket="$W/munge.socket" --key-file="$W/munge.key" --pid-file="$W/munged.pid" \
    --log-file="$W/munged.log" --seed-file="$W/munged.seed"
slurmctld -f "$SLURM_CONF"
# Each slurmd in its node's network namespace (nsenter: `ip netns exec` would remount /sys and hide
# the cgroup file system slurmd reads) and in its own UTS namespace named as the node, so the jobs
# it starts see that hostname and their provenance records name the node.
for n in "${NODE_NAMES[@]}"; do
    nsenter --net="/run/netns/$n" unshare --uts sh -c "hostname $n && exec slurmd -f $SLURM_CONF"
done
for i in $(seq 60); do
    idle=$(sinfo -h -N -t idle -o %N 2>/dev/null | sort -u | wc -l)
    [ "$idle" = "$NODES" ] && break
    [ "$i" = 60 ] && die "$idle of $NODES nodes came up (sinfo -N: $(sinfo -h -N 2>&1 | xargs); logs in $W)"
    sleep 1
done
say "$NODES-node cluster up: ${NODE_NAMES[*]} on $NET.0/24, $CPUS CPUs and $((MEM / NODES)) MB each"

# --- 4. the smoke DAG on SLURM, with one job cancelled ------------------------------------------
export PATH="$VENV/bin:$PATH"
clone() {  # a fresh clone of HEAD whose own package is the one imported (PYTHONPATH)
    git clone -q "$REPO" "$1"
    git -C "$1" checkout -q "$(git -C "$REPO" rev-parse HEAD)"
}
clone "$W/slurm"
SMK=(snakemake --profile profiles/slurm --config budget=smoke --jobs $((CPUS * NODES))
     --slurm-init-seconds-before-status-checks 5)
cd "$W/slurm"
export PYTHONPATH="$W/slurm"
# A job of a rule without wildcards that has run a few seconds (its script has started) is
# cancelled; its record would be results/provenance/<rule>/_.json.
"${NICE[@]}" "${SMK[@]}" > "$W/slurm-run1.log" 2>&1 &
SMK_PID=$!
PIDS+=("$SMK_PID")
CANCELLED=""
while kill -0 "$SMK_PID" 2>/dev/null; do
    line=$(squeue -h -t R -o "%i %k %M" | awk '$2 ~ /^rule_[a-z_]+$/ && $3 >= "0:03" {print; exit}')
    if [ -n "$line" ]; then
        read -r jobid comment _ <<< "$line"
        CANCELLED=${comment#rule_}
        scancel "$jobid"
        say "scancel $jobid ($CANCELLED, running)"
        break
    fi
    sleep 1
done
wait "$SMK_PID" && die "the run with a cancelled job succeeded (nothing was cancelled?)" || true
[ -n "$CANCELLED" ] || die "no running job was found to cancel (log: $W/slurm-run1.log)"
[ ! -e "results/provenance/$CANCELLED/_.json" ] || die "cancelled job $CANCELLED left a provenance record"
say "cancelled job left no record; rerunning"
"${NICE[@]}" "${SMK[@]}" > "$W/slurm-run2.log" 2>&1 || die "the rerun failed (log: $W/slurm-run2.log)"
grep -q "^rule $CANCELLED:" "$W/slurm-run2.log" ||
    grep -q "rule $CANCELLED\b" "$W/slurm-run2.log" || die "the rerun did not run $CANCELLED again"
host_of() { "$VENV/bin/python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["host"])' "$1"; }
[[ " ${NODE_NAMES[*]} " == *" $(host_of "results/provenance/$CANCELLED/_.json") "* ]] ||
    die "the rerun's record of $CANCELLED names no node as its host"
# Every node ran jobs, and nothing ran anywhere else (the profile has no local rules).
HOSTS=$("$VENV/bin/python" -c '
import collections, json, pathlib
recs = [p for p in pathlib.Path("results/provenance").rglob("*.json") if p.parent.name != "config"]
n = collections.Counter(json.loads(p.read_text())["host"] for p in recs)
print(" ".join(f"{h}:{k}" for h, k in sorted(n.items())))')
say "jobs per host (provenance records): $HOSTS"
[ "$(echo "$HOSTS" | tr ' ' '\n' | cut -d: -f1 | xargs)" = "${NODE_NAMES[*]}" ] ||
    die "the records' hosts are not exactly the nodes ${NODE_NAMES[*]}: $HOSTS"
JOBS=$(grep -c "_slurm_rpc_submit_batch_job: JobId=" "$W/slurmctld.log" || true)
SLURM_S=$((SECONDS - START))

# --- 5. the same DAG locally, and the claims tables compared ------------------------------------
clone "$W/local"
cd "$W/local"
export PYTHONPATH="$W/local"
"${NICE[@]}" snakemake --cores 2 --config budget=smoke > "$W/local.log" 2>&1 ||
    die "the local run failed (log: $W/local.log)"
for s in "${CLAIMS[@]}"; do
    f=results/$s/claims.csv
    cmp -s "$W/slurm/$f" "$W/local/$f" || die "$f differs between SLURM and local runs"
done
say "claims tables identical (SLURM vs local --cores 2): ${CLAIMS[*]}"
say "SLURM jobs submitted: $JOBS (both runs; one job cancelled, then rerun)"
say "wall time: $((SECONDS - START)) s (SLURM part $SLURM_S s)"

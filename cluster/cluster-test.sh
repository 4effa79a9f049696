#!/usr/bin/env bash
# `make cluster-test`: a one-node SLURM cluster on this machine, the smoke DAG through
# profiles/slurm in a fresh clone, and the proof that it gives what a local run gives
# (docs/cluster.md, "The local cluster").
#
#  1. installs slurmctld, slurmd, slurm-client and munge from Debian if missing (needs root);
#  2. writes a one-node slurm.conf (proctrack/linuxproc, task/none, no accounting; the node's CPUs
#     and memory as `slurmd -C` reads them) and a munge key into a scratch folder;
#  3. starts munged, slurmctld and slurmd (no systemd) and stops them by pid on exit, whatever
#     happens (trap);
#  4. clones the repository's HEAD, runs `snakemake --profile profiles/slurm --config budget=smoke`,
#     cancels one running job with scancel, checks that it left no provenance record, reruns
#     (--rerun-incomplete, in the profile) and checks that the job ran again and recorded its host;
#  5. runs the same DAG locally (`--cores 2`) in a second clone and compares every claims table:
#     they must be identical, byte for byte.
# Prints the wall time and the number of jobs submitted to SLURM. Exit status 0 only when all holds.
#
# Environment: VENV (default .venv, with `.[cluster]` installed), KEEP=1 keeps the scratch folder.
set -euo pipefail

REPO=$(git rev-parse --show-toplevel)
VENV=$(cd "$REPO" && realpath "${VENV:-.venv}")
START=$SECONDS
NICE=(nice -n 5)
PKGS=(slurmctld slurmd slurm-client munge)
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
cleanup() {
    local rc=$?
    for f in slurmd slurmctld munged; do
        if [ -s "$W/$f.pid" ]; then
            kill "$(cat "$W/$f.pid")" 2>/dev/null || true
        fi
    done
    for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done
    [ "$(readlink /etc/slurm/slurm.conf 2>/dev/null)" = "$W/slurm.conf" ] && rm -f /etc/slurm/slurm.conf
    if [ "${KEEP:-0}" = 1 ] || [ $rc != 0 ]; then say "scratch folder kept: $W"; else rm -rf "$W"; fi
    exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

HOST=$(hostname -s)
mungekey --create --keyfile="$W/munge.key" --force
# The node as slurmd sees it (CPUs, sockets, cores, threads, memory), minus its uptime.
NODE=$(slurmd -C | sed -n 's/^\(NodeName=.*\)$/\1/p' | head -1)
[ -n "$NODE" ] || die "slurmd -C gave no NodeName line"
cat > "$W/slurm.conf" <<EOF
ClusterName=esnaptest
SlurmctldHost=$HOST(127.0.0.1)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$W/munge.socket
SlurmUser=root
SlurmdUser=root
SlurmctldPort=${SLURMCTLD_PORT:-6817}
SlurmdPort=${SLURMD_PORT:-6818}
StateSaveLocation=$W/state
SlurmdSpoolDir=$W/spool
SlurmctldPidFile=$W/slurmctld.pid
SlurmdPidFile=$W/slurmd.pid
SlurmctldLogFile=$W/slurmctld.log
SlurmdLogFile=$W/slurmd.log
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
$NODE NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
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
slurmd -f "$SLURM_CONF"
for i in $(seq 60); do
    state=$(sinfo -h -o %t 2>/dev/null || true)
    [ "$state" = idle ] && break
    [ "$i" = 60 ] && die "the node did not come up (sinfo: '$state'; logs in $W)"
    sleep 1
done
say "one-node cluster up: $NODE"

# --- 4. the smoke DAG on SLURM, with one job cancelled ------------------------------------------
export PATH="$VENV/bin:$PATH"
clone() {  # a fresh clone of HEAD whose own package is the one imported (PYTHONPATH)
    git clone -q "$REPO" "$1"
    git -C "$1" checkout -q "$(git -C "$REPO" rev-parse HEAD)"
}
clone "$W/slurm"
SMK=(snakemake --profile profiles/slurm --config budget=smoke --jobs 4
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
grep -q "\"host\": \"$(hostname)\"" "results/provenance/$CANCELLED/_.json" ||
    die "the rerun's record of $CANCELLED names no host"
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

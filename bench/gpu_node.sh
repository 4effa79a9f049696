#!/usr/bin/env bash
# The paper budget on one GPU node (docs/cluster.md, "One GPU node"): a short check of the GPU
# path on a finished run's models (bench/device_stages.py), then `snakemake all` on this tree with
# the searches' rollouts and the GRU seeds on cuda, one job per run and per seed, all cores,
# sampled every second (load, Snakemake's own CPU, the GPU's busy % and memory); then each stage's
# share (bench/timeline.py) and the results, packed.
#
#   bench/gpu_node.sh OUT_DIR [CHECK_RESULTS]     env: CORES (all), DEADLINE_S (3600), BUDGET (paper), PYTHON
#
# DEADLINE_S bounds the whole script: the run is stopped (SIGINT, as Ctrl-C) when too little is
# left to pack what it made; run the script again to go on (--rerun-incomplete). When the check
# fails, the run goes on with the rollouts on the CPU, so the call still measures the node.
set -u
OUT=$1 CHECK=${2:-}
PY=${PYTHON:-python3} CORES=${CORES:-$(nproc)} T0=$(date +%s) END=$(($(date +%s) + ${DEADLINE_S:-3600} - 40))
mkdir -p "$OUT"
TMP=$(mktemp -d)  # the check's log and the node's config, beside nothing else
# MuJoCo's figures render offscreen through the NVIDIA EGL vendor library where the node has it.
egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f $egl ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
export MUJOCO_GL=egl PYTHONUNBUFFERED=1
{
  date -u; nproc; free -g | head -2; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv
  $PY -c 'import sys, torch, numpy, pandas, snakemake, mujoco; print(sys.version.split()[0], "torch", torch.__version__, "numpy", numpy.__version__, "pandas", pandas.__version__, "snakemake", snakemake.__version__, "mujoco", mujoco.__version__)'
} >"$OUT/env.txt" 2>&1
cat "$OUT/env.txt"

DEV=cuda
if [ -n "$CHECK" ]; then
  echo "== check: the GPU path on $CHECK"
  timeout 150 $PY bench/device_stages.py "$CHECK" --device cuda --generations 3 --short 2 --skip train,cpu \
    --out "$OUT/check.json" >"$TMP/check.log" 2>&1 || DEV=cpu
  grep -q '"error"' "$OUT/check.json" 2>/dev/null && DEV=cpu
  tee -a "$OUT/env.txt" <"$TMP/check.log"
  echo "== rollouts and training on: $DEV"
fi

echo "== snakemake --cores $CORES all, budget ${BUDGET:-paper} (stops by $((END - T0)) s)"
s0=$(date +%s%N)
# read over config.yaml (as profiles/slurm/seeds.yaml is): --config would pass `false` as a string
printf 'policy: {device: %s, batch_runs: false}\ndynamics: {device: %s, seeds_in_one_job: false}\n' $DEV $DEV |
  tee -a "$OUT/env.txt" >"$TMP/node.yaml"
$PY -m snakemake --cores "$CORES" all --rerun-incomplete --keep-going --configfile "$TMP/node.yaml" \
  --config budget="${BUDGET:-paper}" >"$OUT/run.log" 2>&1 &
pid=$!
$PY bench/sample_load.py "$OUT/samples.tsv" --pid $pid --every 1 --gpu 2>>"$OUT/run.log" &
while kill -0 $pid 2>/dev/null; do
  if [ "$(date +%s)" -ge "$END" ]; then
    echo "deadline: stopping the run" | tee -a "$OUT/run.log"
    kill -INT $pid; sleep 20; kill -KILL $pid 2>/dev/null
  fi
  sleep 1
done
wait $pid; rc=$?
echo "snakemake rc=$rc wall_ms=$((($(date +%s%N) - s0) / 1000000))" | tee -a "$OUT/env.txt"
tail -5 "$OUT/run.log"

log=$(ls -t .snakemake/log/*.snakemake.log 2>/dev/null | head -1)
[ -n "$log" ] && $PY bench/timeline.py "$log" --cores "$CORES" --png "$OUT/timeline.png" --samples "$OUT/samples.tsv" \
  >"$OUT/timeline.txt" 2>&1
cat "$OUT/timeline.txt"
tar czf "$OUT/results.tgz" --exclude='*.pkl' --exclude=results/data --exclude=results/splits \
  --exclude=results/crate --exclude=results/provenance --exclude=results/report.html \
  results benchmarks logs .snakemake/log 2>/dev/null
ls -la "$OUT"

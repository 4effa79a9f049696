# Shared by every stage: the group plan, shards, and where a group's files live.
import glob
import os
import re
import sys

# The package beside the Snakefile, installed or not.
sys.path.insert(0, workflow.basedir)

from dataclasses import asdict
from pathlib import Path

from embodied_snap import budget, protocol, runconfig
from embodied_snap import sealed
from embodied_snap.lineage import policy as SEPARATION
from embodied_snap.lineage.groups import deployment_dir
from embodied_snap.lineage.imports import code_inputs
from embodied_snap.lineage.records import job_environment, per_shard_name
from embodied_snap.paper.sections import category as category_of
from embodied_snap.plan import PlanError
from embodied_snap.policy.evaluations import evaluations, training_targets
from embodied_snap.rawformat import RecordingError, group_paths
from embodied_snap.scheduling import local_runs_without_rate_limit
from embodied_snap.verdicts import ACQUIRED, workflow_gate

# A local run's scheduler without Snakemake's job rate limit, whose timers made the scheduler's own
# CPU grow with every finished job (embodied_snap/scheduling.py).
local_runs_without_rate_limit()

# Every job's Python starts watching its reads before its script's first line (docs/lineage.md,
# "From the interpreter's start"): jobs inherit this process's environment, on a cluster node too,
# where the job's own snakemake reads this file again.
os.environ.update(job_environment())

RAW = config["raw_data"]["dir"]
BUDGET = config["budgets"][config["budget"]]
TWIN = config["raw_data"]["source"] == "twin"

# What the schema cannot judge (names left to their tables: evidence sets and categories,
# architectures; the group id pattern): a bad one stops here in one line, as a schema error does
# (embodied_snap/runconfig.py).
CONFIG_ERROR = runconfig.beyond_schema_error(config)
if CONFIG_ERROR:
    sys.exit(f"error: {CONFIG_ERROR}")

# raw_data/ and results/ hold one budget's run at a time (docs/design.md, "Budgets"): asking for
# another stops here with exactly one line (no WorkflowError frame around it), naming both
# budgets and the commands that fit.
try:
    budget.claim(config, argv=sys.argv)
except budget.BudgetError as e:
    sys.exit(f"error: {e}")


def protocol_params(*sections):
    """The protocol sections a job uses, as a param: a changed value reruns exactly those jobs."""
    return protocol.params(config, *sections)


# The plan and the gate decide before the DAG exists (docs/data.md, "The gate"): a broken
# index.csv, a bad id, a stray folder or a broken recording stops the run with one line, and no
# job runs, so nothing under results/ changes until the user fixes the file or excludes the
# group (--config raw_data='{exclude: [id]}'). It is `esnap validate`'s function with the same
# inputs, with either rig: every recording already on disk is judged now, against its index.csv
# row once index.csv exists; with the simulated rig, a shard recorded during this run is judged by
# its validate_shard job before any job reads it (validated).
try:
    PLAN, GATE = workflow_gate(config)
except (PlanError, RecordingError) as e:
    raise WorkflowError(f"error: {e}") from None
EXCLUDED = PLAN.attrs["excluded"]
LIMITS = GATE.limits

SHARDS = {s: list(g.group_id) for s, g in PLAN.groupby("shard", sort=True)}
ROLE_SHARDS = {
    r: sorted(PLAN[PLAN.role == r].shard.unique())
    for r in ("train", "validation", "sealed")
}
# A shard resampled onto the protocol's grid (paper IV-A: 50 Hz): the one place its path is spelled,
# results/data/50hz/{shard}.parquet, for the rule that writes it and every rule that reads it.
RESAMPLED_SHARD = f"results/data/{protocol.GRID_HZ}hz/{{shard}}.parquet"


# Job priorities (docs/design.md, "Scheduling"): FIRST for a job that must not wait (it reads
# recordings, or it is a shared run or reads only those), then LONG for the other policy
# searches, so that the short jobs (evaluations, GRU validations, figures) fill the cores beside
# the last searches instead of delaying them; then DRAW for a figure, the longest of the short
# jobs (matplotlib: 1.5-2 s, a claims table 0.5 s) and what a rerun waits for; 0 else.
FIRST, LONG, DRAW = 3, 2, 1


def reads_recordings(wildcards, input):
    """Priority of a job: FIRST if it reads recordings. Such a job has hundreds of inputs, and
    Snakemake examines the inputs of every waiting job at each scheduling round, so none may wait
    behind the long light jobs (GRU training, policy search)."""
    return FIRST if any(str(f).startswith(f"{RAW}/") for f in input) else 0


def imports(script):
    """Code inputs of a rule: the package modules workflow_scripts/<script>.py imports,
    transitively (read from the sources, never typed), so that editing a module reruns exactly
    the jobs that reach it. Snakemake itself tracks only a job's own script."""
    return code_inputs(f"workflow_scripts/{script}.py", workflow.basedir)


def group_files(gids):
    return [str(p) for g in gids for p in group_paths(RAW, g).values()]


def shard_raw(wildcards):
    """A shard's recordings (with the simulated rig, its acquisition rule's outputs)."""
    return group_files(SHARDS[wildcards.shard])


def raw_index():
    return f"{RAW}/index.csv"


def select(**where):
    """Plan rows matching `where` (plan columns, a value or a list of values)."""
    sel = PLAN
    for col, val in where.items():
        sel = sel[sel[col].isin(val if isinstance(val, (list, tuple)) else [val])]
    return sel


def raw_of(**where):
    """The recordings of the groups matching `where`, e.g.
    raw_of(evidence_set="dynamics", role="train", category="characterisation").
    Only those groups' files become inputs, so the DAG shows exactly which groups a fit saw.
    """
    return group_files(select(**where).group_id)


def raw_dir_of(recording):
    """<raw>/groups/<id>/<file> (group_paths) -> <raw>: a path param read off a job's files, as
    `snakemake --lint` asks of a path prefix; it is config raw_data.dir."""
    return str(Path(recording).parents[2])


def raw_dir(wildcards, input):
    """A param: the raw directory of a job that reads recordings (`raw` input)."""
    return raw_dir_of(input.raw[0])


def metas_of(**where):
    """raw_of, the meta.json files alone."""
    return [f for f in raw_of(**where) if f.endswith("meta.json")]


def ancient_raw_of(**where):
    """raw_of, marked ancient: for a record that must not follow the files' times."""
    return [ancient(f) for f in raw_of(**where)]


def validated(**where):
    """The validation records of the shards holding the groups matching `where`: a rule that reads
    recordings lists these too, so it runs only on recordings that passed validation."""
    shards = sorted(select(**where).shard.unique())
    return expand("results/raw/shards/{shard}.json", shard=shards)


# The HTML report (docs/report.md): the ledger job writes each item's caption here (its static
# caption from report/, the ledger's numbers for its paper sections, its lineage).
CAPTIONS = "results/report"


def caption(name):
    return f"../{CAPTIONS}/{name}.rst"


def category(name):
    """A figure's report category: the paper section its static caption names."""
    return category_of(Path(workflow.basedir, "report", f"{name}.rst").read_text())


def claims_tables(wildcards=None):
    """Every stage's claims table, from the rules that write one (results/<stage>/claims.csv):
    a new stage's table joins the ledger and the separation proof without an edit here.
    """
    return sorted(
        {
            str(f)
            for r in workflow.rules
            for f in r.output
            if re.fullmatch(r"results/(?!tables/)[a-z_]+/claims\.csv", str(f))
        }
    )


def claims_artifacts(wildcards=None):
    """The JSON artifacts the claims tables' rules read or write: the ledger reads each one's
    recordings, for the recordings of each number (docs/lineage.md, "A number's lineage").
    """
    tables = set(claims_tables())
    return sorted(
        {
            str(f)
            for r in workflow.rules
            if tables & {str(o) for o in r.output}
            for f in [*r.input, *r.output]
            if isinstance(f, str) and re.fullmatch(r"results/\S+\.json", f)
        }
    )


# Fig. 1b shows the first attachment trial: a recorded strike at a target, every release labelled.
FIG1_GROUP = min(select(evidence_set="attachment").group_id)


# --- What the stages hand each other --------------------------------------------------------------
# The files a stage reads from an earlier one are named here, once, so that each rule file reads
# only this file and its own names, and the include order carries no meaning.

# The dynamics model (rules/dynamics.smk): the GRU ensemble, and the training groups whose holds
# the hold bank is built from.
DYNAMICS_DIR = "results/dynamics"
DYNAMICS_CONFIG = config["dynamics"]
DYNAMICS_MODELS = expand(
    f"{DYNAMICS_DIR}/models/seed{{seed}}.pt", seed=DYNAMICS_CONFIG["seeds"]
)
HOLD = dict(evidence_set="dynamics", role="train")
HOLD_GROUPS = sorted(select(**HOLD).group_id)

# Policy search (rules/policy.smk): the runs of every architecture and seed, the shared ones that
# the ablation and the deployment read, and the simulator each later stage rolls policies out in.
POLICY_DIR = "results/policy"
POLICY_CONFIG = config["policy"]
POLICY_BUDGET = BUDGET["policy"]
POLICY_RUNS_OF = [
    (arch, seed) for arch, n in POLICY_BUDGET["seeds"].items() for seed in range(n)
]
# The target sets a search draws: training ones for every generation, selection, evaluation.
TARGET_SIZES = dict(
    training=training_targets(
        POLICY_BUDGET["generations"], POLICY_BUDGET["targets_per_candidate"]
    ),
    selection=POLICY_BUDGET["selection_targets"],
    evaluation=POLICY_BUDGET["evaluation_targets"],
)
POLICY_RUNS = [f"{POLICY_DIR}/runs/{a}_seed{s}.json" for a, s in POLICY_RUNS_OF]
POLICY_EVALUATIONS = [
    f"{POLICY_DIR}/eval/{a}_seed{s}.parquet" for a, s in POLICY_RUNS_OF
]
SHARED_RUNS = [
    f"{POLICY_DIR}/runs/shared_seed{s}.json"
    for s in range(POLICY_BUDGET["seeds"]["shared"])
]
SIMULATOR = dict(
    models=DYNAMICS_MODELS,
    bank=f"{DYNAMICS_DIR}/hold_bank.npz",
    snap="results/characterize/snap.json",
    workspace=f"{POLICY_DIR}/workspace.json",
)
# The policy config a job's params carry: how the searches are scheduled (policy.batch_runs) is no
# job's param, so switching it reruns only the searches.
POLICY_PARAMS = {k: v for k, v in POLICY_CONFIG.items() if k != "batch_runs"}
SIMULATOR_PARAMS = dict(
    policy=POLICY_PARAMS,
    after_s1=DYNAMICS_CONFIG["after_s1_s"],
    ee_m=config["rig"]["end_effector_m"],
    protocol=protocol_params("sampling", "windows", "primitive"),
)

# A job that rolls the ensemble out holds the GPU when config policy.device is cuda (profiles/slurm:
# --gpus=1); auto is decided on the node, so it asks for none.
SIMULATOR_RESOURCES = dict(gpu=int(POLICY_CONFIG["device"] == "cuda"))


def shared_run(wildcards):
    """Priority of a policy evaluation: FIRST for a shared run (SHARED_RUNS), which the ablation
    and the deployment read."""
    return (
        FIRST
        if f"{POLICY_DIR}/runs/{wildcards.arch}_seed{wildcards.seed}.json"
        in SHARED_RUNS
        else 0
    )


def search_priority(wildcards):
    """Priority of a policy search: FIRST for a shared run, LONG for the others (longest first)."""
    return shared_run(wildcards) or LONG


# The deployment (rules/deploy.smk): the manifest, and the trials recorded with it. Trials exist,
# or the simulated rig records them: Table II and Fig. 7 are built. On a real rig they are recorded
# in the lab after export (`esnap deploy`, docs/deployment.md); until then the workflow builds the
# manifest and stops there.
DEPLOYMENT_DIR = "results/deployment"
DEPLOYMENT_RAW = deployment_dir(RAW)
DEPLOYED = TWIN or Path(DEPLOYMENT_RAW, "index.csv").exists()
# Everything the manifest hashes: the separation proof re-hashes them (nothing changed after export).
MANIFEST_INPUTS = dict(
    runs=SHARED_RUNS,
    workspace=f"{POLICY_DIR}/workspace.json",
    servo="results/characterize/servo.json",
    bank=f"{DYNAMICS_DIR}/hold_bank.npz",
    snap="results/characterize/snap.json",
    models=DYNAMICS_MODELS,
)
MANIFEST_FILES = [
    f for v in MANIFEST_INPUTS.values() for f in (v if isinstance(v, list) else [v])
]

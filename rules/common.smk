# Shared by every stage: the group plan, shards, and where a group's files live.
import sys

# The package beside the Snakefile, installed or not.
sys.path.insert(0, workflow.basedir)

from embodied_snap import protocol
from embodied_snap.lineage.imports import code_inputs
from embodied_snap.plan import PlanError, load_plan
from embodied_snap.rawformat import group_paths

RAW = config["raw_data"]["dir"]
BUDGET = config["budgets"][config["budget"]]
TWIN = config["raw_data"]["source"] == "twin"

# A protocol some stage cannot run stops the workflow here, in one line naming the stage.
UNSUPPORTED = protocol.unsupported(config)
if UNSUPPORTED:
    raise WorkflowError(UNSUPPORTED)


def protocol_params(*sections):
    """The protocol sections a job uses, as a param: a changed value reruns exactly those jobs."""
    return protocol.params(config, *sections)


try:
    PLAN = load_plan(config, RAW)
except PlanError as e:
    raise WorkflowError(str(e)) from None

SHARDS = {s: list(g.group_id) for s, g in PLAN.groupby("shard", sort=True)}
ROLE_SHARDS = {
    r: sorted(PLAN[PLAN.role == r].shard.unique())
    for r in ("train", "validation", "sealed")
}


def imports(script):
    """Code inputs of a rule: the package modules workflow_scripts/<script>.py imports,
    transitively (read from the sources, never typed), so that editing a module reruns exactly
    the jobs that reach it. Snakemake itself tracks only a job's own script."""
    return code_inputs(f"workflow_scripts/{script}.py", workflow.basedir)


def group_files(gids):
    return [str(p) for g in gids for p in group_paths(RAW, g).values()]


def shard_raw(wildcards):
    """A shard's recordings; with the simulated rig they exist once its acquisition ran."""
    if TWIN:
        checkpoints.twin_acquire.get(shard=wildcards.shard)
    return group_files(SHARDS[wildcards.shard])


TWIN_REPORTS = []  # the simulated rig adds its reports


def raw_index():
    return f"{RAW}/index.csv"


def select(**where):
    """Plan rows matching `where` (plan columns, a value or a list of values)."""
    sel = PLAN
    for col, val in where.items():
        sel = sel[sel[col].isin(val if isinstance(val, (list, tuple)) else [val])]
    return sel


def raw_of(**where):
    """Input function: the recordings of the groups matching `where`, e.g.
    raw_of(evidence_set="dynamics", role="train", category="characterisation").
    Only those groups' files become inputs, so the DAG shows exactly which groups a fit saw.
    """

    def files(wildcards):
        sel = select(**where)
        if TWIN:
            for s in sel.shard.unique():
                checkpoints.twin_acquire.get(shard=s)
        return group_files(sel.group_id)

    return files


def validated(**where):
    """The validation records of the shards holding the groups matching `where`: a rule that reads
    recordings lists these too, so it runs only on recordings that passed validation."""
    shards = sorted(select(**where).shard.unique())
    return expand("results/raw/shards/{shard}.json", shard=shards)

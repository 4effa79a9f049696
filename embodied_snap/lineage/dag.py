"""The Snakemake workflow as plain data: the one place that uses Snakemake's private API.

The public API (SnakemakeApi -> workflow -> dag) builds a DAG but exposes neither the parsed
rules nor a DAG object, so this reads `WorkflowApi._workflow` and does what `DAGApi.printdag`
does internally: prepare and build the DAG of the Workflow and read `workflow.dag`.
tests/test_lineage_dag.py fails loudly when a Snakemake upgrade breaks it.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from pathlib import Path

from .records import instance


def _norm(p) -> str:
    return os.path.normpath(str(p)).replace(os.sep, "/")


@contextmanager
def _workflow(workdir, configfiles, config_overrides):
    """The parsed Workflow of the Snakefile in `workdir`, silent, writing no log file."""
    from snakemake.api import SnakemakeApi
    from snakemake.settings.enums import Quietness
    from snakemake.settings.types import ConfigSettings, OutputSettings, ResourceSettings

    cwd = os.getcwd()
    workdir = Path(workdir).resolve()
    try:
        out = OutputSettings(quiet={Quietness.ALL}, enable_file_logging=False)
        with SnakemakeApi(out) as api:
            wf_api = api.workflow(
                ResourceSettings(cores=1),
                ConfigSettings(configfiles=[Path(c).resolve() for c in configfiles or ()],
                               config=dict(config_overrides or {})),
                snakefile=workdir / "Snakefile",
                workdir=workdir,
            )
            yield wf_api
    finally:
        os.chdir(cwd)


def _plain(res):
    """A rule's resource as declared: its number, or None when a function computes it per job."""
    try:
        return getattr(res, "value", res)
    except ValueError:  # Snakemake: "must be evaluated within the context of a rule"
        return None


def _threads(r) -> int | None:
    t = _plain(r.resources.get("_cores"))
    return t if isinstance(t, int) else None


def rule_table(workdir=".", configfiles=None, config_overrides=None) -> dict[str, dict]:
    """{rule: {script: file name or None, code: its named input `code` (when not a function),
    benchmark: the regex of its benchmark path or None, threads: its `threads:` (None when a
    function), resources: its declared resources that are plain numbers}}."""
    with _workflow(workdir, configfiles, config_overrides) as wf_api:
        out = {}
        for r in wf_api._workflow.rules:
            code = getattr(r.input, "code", None)
            out[r.name] = dict(script=Path(r.script).name if r.script else None,
                               code=None if code is None or callable(code) else [_norm(f) for f in code],
                               benchmark=r.benchmark.regex().pattern if r.benchmark else None,
                               threads=_threads(r),
                               resources={k: v for k, v in ((k, _plain(v)) for k, v in r.resources.items())
                                          if not k.startswith("_") and isinstance(v, int)})
        return out


RETRIES = 5
CONCURRENT = "although it existed before"  # Snakemake's message for a file deleted while it read the tree


def build_dag(workdir=".", configfiles=None, config_overrides=None, targets=("all",)) -> list[dict]:
    """The jobs of the workflow in `workdir`, forceall (jobs whose outputs exist are in it):
    [{rule, wildcards, input, output, down: [indices of jobs that consume its outputs]}]."""
    from snakemake.exceptions import WorkflowError
    from snakemake.settings.types import DAGSettings

    for attempt in range(RETRIES):
        try:
            return _build(workdir, configfiles, config_overrides, targets, DAGSettings)
        except WorkflowError as e:
            # Inside a run (the separation check) a job beside this one may delete and rewrite an
            # output between Snakemake's listing and its stat of the file; the DAG is the same.
            if CONCURRENT not in str(e) or attempt == RETRIES - 1:
                raise
            time.sleep(1)


def _build(workdir, configfiles, config_overrides, targets, DAGSettings) -> list[dict]:
    with _workflow(workdir, configfiles, config_overrides) as wf_api:
        wf_api.dag(DAGSettings(targets=frozenset(targets), forceall=True))  # installs the settings
        wf = wf_api._workflow
        wf._prepare_dag(forceall=True, ignore_incomplete=True, lock_warn_only=True)
        wf._build_dag()
        dag = wf.dag
        jobs = list(dag.jobs)
        idx = {j: i for i, j in enumerate(jobs)}
        nodes = []
        for j in jobs:
            rule, wildcards = instance(j.rule.name, {k: str(v) for k, v in j.wildcards.items()})
            nodes.append(dict(rule=rule, wildcards=wildcards, input=[_norm(f) for f in j.input],
                              output=[_norm(f) for f in j.output], down=[]))
        for j in jobs:
            for dep in dag.dependencies[j]:
                nodes[idx[dep]]["down"].append(idx[j])
        return nodes

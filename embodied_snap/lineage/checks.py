"""`esnap check-separation`: prove DESIGN.md section 3 (what each evidence set may feed).

Two independent proofs over the same POLICY:
- static, on the Snakemake DAG (built through the Snakemake API): from every job that carries a
  `shard` wildcard of an evidence set or split role, and from `raw_data/twin_truth.json`, no path
  reaches a rule that source must never feed;
- on the provenance records of what actually ran: no forbidden group reached an artifact, the
  window files hold only groups of their role, sealed groups are never train/validation, the
  policy target sets are disjoint, and nothing but twin_validation read the twin's truth.

Each violation is one line naming the artifact, the group (or shard) and the rule broken.
"""

from __future__ import annotations

import os
from collections import deque
from fnmatch import fnmatchcase
from pathlib import Path

from .records import SPLIT_CSV, TWIN_TRUTH, group_of, load_groups, load_records

# --- The policy: DESIGN.md section 3 as data. The one place to change what may feed what. -------
#
# Patterns are fnmatch patterns over a job label, `rule` or `rule(k=v,...)` (so `windows(role=train)`
# names one wildcard instance). A source reaches a job if data flows from it to the job through
# any chain of jobs. `never`: the source must not reach these (unless `except_` matches);
# `only`: the source may reach nothing else. `held_out` marks sets kept out of model fitting
# (exported as esnap:held_out). `rule` is the sentence of DESIGN section 3 a violation breaks.

# Jobs that carry only metadata about recordings (checks, manifest, index, split table, the lineage
# itself, the overview figure of the recordings): allowed everywhere, and data does not flow
# *through* them, otherwise the raw manifest, which reads every group, would make every group
# reach everything downstream of it.
BOOKKEEPING = (
    "validate_*", "raw_manifest", "twin_index", "split",
    "check_separation", "prov_export", "fig_data_overview",
)
# Jobs whose outputs are statements about the whole run (the separation proof, the PROV export).
# Reports list them as inputs only to run after them; `esnap audit` does not descend into them.
GATES = ("check_separation", "prov_export")
# Figures and tables (and the folders that assemble them) report results; the twin's reports describe
# the simulated rig. Sealed groups may reach these (after the sealed evaluation).
REPORTS = ("fig_*", "figures", "table_*", "tables", "twin_phenomena", "twin_validation")
# Rules whose `shard` wildcard marks a job as reading one shard's raw groups (static sources).
SOURCE_RULES = ("twin_acquire", "validate_shard", "resample_shard")
_DYNAMICS = ("windows*", "dynamics_*")  # the dynamics datasets and everything fit from them
_POLICIES = ("policy_*",)

POLICY: dict[str, dict] = {
    "servo_calibration": dict(
        never=_DYNAMICS + _POLICIES, held_out=False,
        rule="servo_calibration may feed kinematics, servo rate fit and ceilings, never the dynamics model or policies"),
    "attachment": dict(
        never=_DYNAMICS + _POLICIES, held_out=False,
        rule="attachment may feed the speed/angle attachment model, never the dynamics model or policies"),
    "release_mode": dict(
        never=_DYNAMICS, held_out=False,
        rule="release_mode may feed Fig. 2b, never the dynamics model"),
    "delay_sweep": dict(
        never=("windows*", "characterize_*", "dynamics_*", "policy_*"),
        except_=("characterize_delay_sweep*", "dynamics_gate*"), held_out=True,
        rule="delay_sweep may feed the timing set and the timing/dynamics gates, never any model fit"),
    "held_base": dict(
        never=_DYNAMICS + _POLICIES, held_out=False,
        rule="held_base may feed the trigger-detection comparison, never the dynamics model or policies"),
    "deployment": dict(
        never=("windows*", "characterize_*", "dynamics_*", "policy_*", "deploy_manifest*"), held_out=True,
        rule="deployment may feed Table II and Fig. 7, nothing upstream of the manifest"),
    # The dynamics corpus by split role (440 / 78 / 20).
    "train": dict(
        never=("windows(role=validation)", "windows(role=sealed)"), held_out=False,
        rule="train groups stay in the training windows"),
    "validation": dict(
        never=("windows(role=train)", "windows(role=sealed)", "dynamics_hold*", "characterize_snap*"),
        held_out=True,
        rule="validation groups stay in the validation windows; hold bank and snap classifier use training groups only"),
    "sealed": dict(
        only=("twin_acquire*", "resample_shard*", "windows(role=sealed)", "dynamics_sealed_eval*") + REPORTS,
        held_out=True,
        rule="sealed groups may feed only the sealed windows, the single sealed evaluation and reports"),
    TWIN_TRUTH: dict(
        readers=("twin_validation",), only=("twin_validation",) + REPORTS, held_out=True,
        rule="only twin_validation reads the simulated rig's ground truth"),
    # The simulated target sets (files): what may read each, and where their data may flow.
    "results/policy/targets_selection.parquet": dict(
        readers=("policy_search", "policy_fixed"),
        only=("policy_search*", "policy_evaluate*", "policy_fixed*", "policy_summary*") + REPORTS, held_out=False,
        rule="the 64 selection targets select policies; they never feed the evaluation targets' own use"),
    "results/policy/targets_evaluation.parquet": dict(
        readers=("policy_evaluate", "policy_fixed"),
        only=("policy_evaluate*", "policy_fixed*", "policy_summary*") + REPORTS, held_out=True,
        rule="the 400 evaluation targets are read only by the final evaluation, after selection"),
}
# Sources that are files rather than raw groups: their readers are checked, then the usual walk.
FILE_SOURCES = tuple(k for k, v in POLICY.items() if "readers" in v)
# Evidence sets that must never feed any model (exported as held out with validation and sealed).
HELD_OUT = {k for k, v in POLICY.items() if v["held_out"]}
WINDOW_ROLES = ("train", "validation", "sealed")
TARGET_SETS = ("training", "selection", "evaluation")


def label(rule: str, wildcards: dict) -> str:
    return f"{rule}({','.join(f'{k}={v}' for k, v in sorted(wildcards.items()))})" if wildcards else rule


def _match(pats, rule: str, lab: str) -> bool:
    return any(fnmatchcase(lab, p) or fnmatchcase(rule, p) for p in pats)


def is_bookkeeping(rule: str) -> bool:
    return _match(BOOKKEEPING, rule, rule)


def is_gate(rule: str) -> bool:
    return _match(GATES, rule, rule)


def forbidden(source: str, rule: str, wildcards: dict) -> bool:
    """Does DESIGN section 3 forbid data of `source` (evidence set, role or the truth file) to reach
    this job? Sources without a policy row (e.g. 'dynamics' before a split exists) forbid nothing."""
    p = POLICY.get(source)
    if p is None or is_bookkeeping(rule):
        return False
    lab = label(rule, wildcards)
    if "only" in p:
        return not _match(p["only"], rule, lab)
    return _match(p.get("never", ()), rule, lab) and not _match(p.get("except_", ()), rule, lab)


def shard_source(shard: str) -> str:
    """`dynamics_<role>-NN` -> role; `<evidence_set>-NN` -> evidence set (plan.shard)."""
    name = shard.rsplit("-", 1)[0]
    return name.removeprefix("dynamics_") if name.startswith("dynamics_") else name


def _norm(p) -> str:
    return os.path.normpath(str(p)).replace(os.sep, "/")


# --- static: the Snakemake DAG ---------------------------------------------------------------------


def build_dag(workdir=".", configfiles=None, config_overrides=None, targets=("all",)) -> list[dict]:
    """The job graph of the workflow in `workdir` as plain dicts:
    {rule, wildcards, input, output, down: [indices of jobs that consume its outputs]}.

    Goes through the public API as far as it reaches (SnakemakeApi -> workflow -> dag), then
    does what `DAGApi.printdag` does internally (the API exposes no DAG object): prepare and build
    the DAG of the Workflow and read `workflow.dag`. forceall, so jobs whose outputs exist are in it.
    """
    from snakemake.api import SnakemakeApi
    from snakemake.settings.enums import Quietness
    from snakemake.settings.types import ConfigSettings, DAGSettings, OutputSettings, ResourceSettings

    cwd = os.getcwd()
    workdir = Path(workdir).resolve()
    try:
        # Silent, and no log file under .snakemake/log for a check that runs nothing.
        out = OutputSettings(quiet={Quietness.ALL}, enable_file_logging=False)
        with SnakemakeApi(out) as api:
            wf_api = api.workflow(
                ResourceSettings(cores=1),
                ConfigSettings(configfiles=[Path(c).resolve() for c in configfiles or ()],
                               config=dict(config_overrides or {})),
                snakefile=workdir / "Snakefile",
                workdir=workdir,
            )
            wf_api.dag(DAGSettings(targets=frozenset(targets), forceall=True))  # installs the settings
            wf = wf_api._workflow
            wf._prepare_dag(forceall=True, ignore_incomplete=True, lock_warn_only=True)
            wf._build_dag()
            dag = wf.dag
            jobs = list(dag.jobs)
            idx = {j: i for i, j in enumerate(jobs)}
            nodes = [dict(rule=j.rule.name, wildcards={k: str(v) for k, v in j.wildcards.items()},
                          input=[_norm(f) for f in j.input], output=[_norm(f) for f in j.output],
                          down=[]) for j in jobs]
            for j in jobs:
                for dep in dag.dependencies[j]:
                    nodes[idx[dep]]["down"].append(idx[j])
            return nodes
    finally:
        os.chdir(cwd)


def _walk(nodes, starts, source, what):
    """Breadth-first from the start jobs along data flow; one violation per forbidden job reached,
    not followed further (everything after it is tainted by the same breach)."""
    out, seen, parent = [], set(starts), {}
    todo = deque(starts)
    while todo:
        i = todo.popleft()
        for k in nodes[i]["down"]:
            if k in seen:
                continue
            seen.add(k)
            parent[k] = i
            n = nodes[k]
            if is_bookkeeping(n["rule"]) or not n["output"]:
                continue  # target rules (all, figures, ...) write nothing data could flow into
            if forbidden(source, n["rule"], n["wildcards"]):
                chain, c = [], k
                while c is not None:
                    chain.append(label(nodes[c]["rule"], nodes[c]["wildcards"]))
                    c = parent.get(c)
                out.append(f"separation (DAG): {n['output'][0]} (rule {label(n['rule'], n['wildcards'])}) "
                           f"is reachable from {what} via {' > '.join(reversed(chain))}; "
                           f"DESIGN 3: {POLICY[source]['rule']}")
                continue
            todo.append(k)
    return out


def dag_violations(nodes: list[dict], groups: dict | None = None) -> tuple[list[str], dict]:
    """Violations of POLICY on a job graph. `groups` (load_groups) classifies raw group files that a
    job lists as inputs: a job outside the shard rules that reads recordings directly is a source too."""
    shards: dict[str, list[int]] = {}
    for i, n in enumerate(nodes):
        if n["rule"] in SOURCE_RULES and "shard" in n["wildcards"]:
            shards.setdefault(n["wildcards"]["shard"], []).append(i)
    out = []
    for shard, starts in sorted(shards.items()):
        src = shard_source(shard)
        if src in POLICY:
            out += _walk(nodes, starts, src, f"{src} shard {shard}")
    n_direct = 0
    for i, n in enumerate(nodes):
        if is_bookkeeping(n["rule"]):
            continue
        is_src = n["rule"] in SOURCE_RULES and "shard" in n["wildcards"]
        own = shard_source(n["wildcards"]["shard"]) if is_src else None  # already walked above
        first: dict[str, str] = {}  # source -> first group of it this job reads
        for f in n["input"]:
            g = group_of(f)
            src = (groups or {}).get(g[0], {}).get("role") if g else None
            if src in POLICY and src != own:
                first.setdefault(src, g[0])
        for src, g in sorted(first.items()):
            n_direct += 1
            if forbidden(src, n["rule"], n["wildcards"]):
                art = n["output"][0] if n["output"] else "(no output)"
                out.append(f"separation (DAG): {art} (rule {n['rule']}) reads raw {src} group {g}; "
                           f"DESIGN 3: {POLICY[src]['rule']}")
            else:
                out += _walk(nodes, [i], src, f"{src} group {g} (read by {label(n['rule'], n['wildcards'])})")
    # File sources (the twin's truth, the target sets): read directly only by the allowed readers,
    # then the usual walk.
    n_readers = 0
    for src in FILE_SOURCES:
        readers = [i for i, n in enumerate(nodes) if src in n["input"]]
        n_readers += len(readers) if src == TWIN_TRUTH else 0
        allowed = POLICY[src]["readers"]
        for i in readers:
            n = nodes[i]
            if n["rule"] not in allowed:
                art = n["output"][0] if n["output"] else "(no output)"
                out.append(f"separation (DAG): {art} (rule {n['rule']}) reads {src}; DESIGN 3: {POLICY[src]['rule']}")
        ok = [i for i in readers if nodes[i]["rule"] in allowed]
        if ok:
            out += _walk(nodes, ok, src, src)
    return out, dict(dag_jobs=len(nodes), dag_source_shards=len(shards), dag_direct_readers=n_direct,
                     dag_truth_readers=n_readers)


def check_dag(workdir=".", configfiles=None, config_overrides: dict | None = None,
              targets=("all",)) -> list[str]:
    nodes = build_dag(workdir, configfiles, config_overrides, targets)
    return dag_violations(nodes, load_groups(workdir))[0]


# --- on the records --------------------------------------------------------------------------------


def _record_violations(root: Path, groups: dict) -> tuple[list[str], dict]:
    by_output = load_records(root)
    recs = {r["_record"]: r for r in by_output.values()}
    fed: dict[str, dict[str, str]] = {}  # record -> {group or truth file -> the source class}
    tainted: dict[str, set] = {}  # record -> sources already reported upstream
    out = []

    def src_of(g):
        if g in FILE_SOURCES:
            return g
        d = groups.get(g, {})
        # The sealed category is sealed whatever split.csv says (a wrong split is reported apart).
        return "sealed" if d.get("category") == "sealed" else (d.get("role") or "unknown")

    def visit(key, stack=()):
        if key in fed:
            return
        r = recs[key]
        f, v, t = {}, {}, set()  # sources fed, the direct input that carried each, sources reported
        for e in r.get("inputs", []):
            p = e["path"]
            go = group_of(p)
            if go or p in FILE_SOURCES:
                g = go[0] if go else p
                f.setdefault(g, src_of(g))
                v.setdefault(g, p)
                continue
            prod = by_output.get(p)
            if prod is None or is_bookkeeping(prod["rule"]) or prod["_record"] in stack:
                continue
            visit(prod["_record"], stack + (key,))
            for g, s in fed[prod["_record"]].items():
                f.setdefault(g, s)
                v.setdefault(g, p)
            t |= tainted[prod["_record"]]
        rule, wc = r["rule"], r.get("wildcards", {})
        art = r["outputs"][0]["path"] if r.get("outputs") else key
        for src in FILE_SOURCES:
            if any(e["path"] == src for e in r.get("inputs", [])):
                t.add(src)  # a direct read is judged by the readers check below, not again here
        by_src: dict[str, list[str]] = {}
        for g, s in f.items():
            by_src.setdefault(s, []).append(g)
        for s, gs in sorted(by_src.items()):
            if s not in t and forbidden(s, rule, wc):
                gs = sorted(gs)
                more = f" (+{len(gs) - 1} more)" if len(gs) > 1 else ""
                what = gs[0] if s in FILE_SOURCES else f"{s} group {gs[0]}{more}"
                out.append(f"separation (records): {art} (rule {label(rule, wc)}) was fed by {what} "
                           f"through {v[gs[0]]}; DESIGN 3: {POLICY[s]['rule']}")
                t.add(s)
        fed[key], tainted[key] = f, t

    for key in sorted(recs):
        if not is_bookkeeping(recs[key]["rule"]):
            visit(key)
    # Nothing but the allowed readers reads a file source, bookkeeping included.
    for key, r in sorted(recs.items()):
        for src in FILE_SOURCES:
            if r["rule"] not in POLICY[src]["readers"] and any(e["path"] == src for e in r.get("inputs", [])):
                art = r["outputs"][0]["path"] if r.get("outputs") else key
                out.append(f"separation (records): {art} (rule {r['rule']}) read {src}; "
                           f"DESIGN 3: {POLICY[src]['rule']}")
    return out, dict(records=len(recs))


def _split_violations(root: Path, groups: dict) -> list[str]:
    out = []
    if not (root / SPLIT_CSV).exists():
        return out
    for g, d in sorted(groups.items()):
        if d["category"] == "sealed" and d["evidence_set"] == "dynamics" and d["role"] in ("train", "validation"):
            out.append(f"separation (split): {SPLIT_CSV} puts sealed group {g} in {d['role']}; "
                       f"DESIGN 3: {POLICY['sealed']['rule']}")
    return out


def _window_violations(root: Path, groups: dict) -> tuple[list[str], int]:
    import numpy as np

    out, n = [], 0
    for role in WINDOW_ROLES:
        p = root / f"results/splits/windows_{role}.npz"
        if not p.exists():
            continue
        n += 1
        with np.load(p, allow_pickle=False) as z:
            ids = sorted(set(str(x) for x in z["group_ids"])) if "group_ids" in z else None
        if ids is None:
            out.append(f"separation (windows): {p.relative_to(root)} has no group_ids array; "
                       "DESIGN 3: the window files must show which groups each model saw")
            continue
        wrong: dict[str, list[str]] = {}  # the role a misplaced group really has -> groups
        for g in ids:
            d = groups.get(g)
            have = d["role"] if d else "unknown (not in index.csv)"
            if d is not None and d["category"] == "sealed":
                have = "sealed"  # a sealed group is sealed whatever split.csv says
            if have != role:
                wrong.setdefault(have, []).append(g)
        for have, gs in sorted(wrong.items()):
            rule_of = POLICY[have]["rule"] if have in POLICY else "windows of a role hold only groups of that role"
            more = f" (+{len(gs) - 1} more)" if len(gs) > 1 else ""
            out.append(f"separation (windows): {p.relative_to(root)} holds group {gs[0]}{more} of role "
                       f"{have} ({SPLIT_CSV}); DESIGN 3: {rule_of}")
    return out, n


def _target_violations(root: Path) -> tuple[list[str], int]:
    from ..io import read_parquet

    sets = {}
    for name in TARGET_SETS:
        p = root / f"results/policy/targets_{name}.parquet"
        if p.exists():
            df = read_parquet(p)
            if "target_id" in df:
                sets[name] = {str(x) for x in df["target_id"]}
            else:  # positions, rounded below any meaningful precision (1 nm)
                sets[name] = {tuple(r) for r in df[["x", "y", "z"]].round(9).itertuples(index=False)}
    out = []
    names = sorted(sets)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            common = sets[a] & sets[b]
            if common:
                out.append(f"separation (targets): results/policy/targets_{b}.parquet shares {len(common)} "
                           f"target(s) with targets_{a}.parquet (first: {sorted(common)[0]}); "
                           "DESIGN 3: training, selection and evaluation targets are disjoint (separate seeds)")
    return out, len(sets)


def check_records(root=".") -> list[str]:
    return _records_check(Path(root))[0]


def _records_check(root: Path) -> tuple[list[str], dict]:
    groups = load_groups(root)
    out, counts = _record_violations(root, groups)
    out += _split_violations(root, groups)
    w, nw = _window_violations(root, groups)
    t, nt = _target_violations(root)
    counts.update(groups=len(groups), window_files=nw, target_sets=nt)
    return out + w + t, counts


def check(root=".", static=True, records=True, **dag_kwargs) -> dict:
    """Both proofs; a DAG that cannot be built is a failed proof, not a pass."""
    root = Path(root)
    violations, checked = [], {}
    if static:
        try:
            wd = dag_kwargs.pop("workdir", root)
            v, c = dag_violations(build_dag(wd, **dag_kwargs), load_groups(wd))
        except Exception as e:  # noqa: BLE001 -- any failure to build the DAG means no proof
            v, c = [f"separation (DAG): could not build the Snakemake DAG: {type(e).__name__}: {e}"], {}
        violations += v
        checked.update(c)
    if records:
        v, c = _records_check(root)
        violations += v
        checked.update(c)
    return dict(ok=not violations, violations=violations, checked=checked)

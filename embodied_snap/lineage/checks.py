"""`esnap check-separation`: prove docs/design.md section 3 (what each evidence set may feed).

Two independent proofs over the same allow list (lineage/policy.py):
- static, on the Snakemake DAG (lineage/dag.py): every rule is named by the policy, and from every
  job that reads a source (a shard of an evidence set or split role, a raw group read directly,
  the twin's truth, a target set) every job reached is one the source may feed;
- on the provenance records of what actually ran: every job a group or file source reached is one
  it may feed, every record is readable and every result file a record used has a record of its
  own, the window files hold only groups of their role, sealed groups are never train/validation,
  and the policy target sets are disjoint.

The raw directory is the configured one. Each violation is one line naming the artifact, the
group (or shard) and the rule broken.
"""

from __future__ import annotations

import json
from collections import deque
from pathlib import Path

import numpy as np

from ..deploy.manifest import ManifestError, inputs_changed, load
from ..io import read_parquet
from . import policy as P
from .dag import build_dag
from .groups import SPLIT_CSV, deployment_dir, group_of, load_groups, twin_truth
from .records import AFTER_RUN, DEFAULT_RAW, RECORDS_DIR, last_config, load_records, raw_dir_of

RULE = "docs/design.md 3"
TARGETS_RULE = "training, selection, evaluation, offset and release targets are disjoint (separate seeds)"


def shard_source(shard: str) -> str:
    """`dynamics_<role>-NN` -> role; `<evidence_set>-NN` -> evidence set (plan.shard)."""
    name = shard.rsplit("-", 1)[0]
    return name.removeprefix("dynamics_") if name.startswith("dynamics_") else name


def file_source(path: str, raw: str) -> str | None:
    """The policy key of a file source at `path`, or None."""
    if path == twin_truth(raw):
        return "twin_truth"
    if path.startswith(deployment_dir(raw) + "/") or path == deployment_dir(raw):
        return "deployment"
    return path if path in P.POLICY and P.POLICY[path].readers else None


def _art(n: dict) -> str:
    """A DAG job's first output."""
    return n["output"][0] if n.get("output") else "(no output)"


def _rart(r: dict, key: str) -> str:
    """A record's first output, or the record itself."""
    return r["outputs"][0]["path"] if r.get("outputs") else key


# --- static: the Snakemake DAG ---------------------------------------------------------------------


def _walk(nodes, starts, source, what):
    """Breadth-first from the start jobs along data flow; one violation per job reached that the
    source may not feed, not followed further (everything after it is tainted by the same breach)."""
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
            if n["rule"] in P.BOOKKEEPING or not n["output"]:
                continue  # metadata only, or a target rule that writes nothing
            if not P.may_feed(source, n["rule"], n["wildcards"]):
                chain, c = [], k
                while c is not None:
                    chain.append(P.label(nodes[c]["rule"], nodes[c]["wildcards"]))
                    c = parent.get(c)
                out.append(f"separation (DAG): {n['output'][0]} (rule {P.label(n['rule'], n['wildcards'])}) "
                           f"is reachable from {what} via {' > '.join(reversed(chain))}; "
                           f"{RULE}: {P.POLICY[source].rule}")
                continue
            todo.append(k)
    return out


def dag_violations(nodes: list[dict], groups: dict | None = None, raw: str = DEFAULT_RAW) -> tuple[list[str], dict]:
    """Violations of the policy on a job graph. `groups` (load_groups) classifies raw group files
    that a job lists as inputs: a job outside the shard rules that reads recordings is a source too."""
    named = P.named_rules()
    out = [f"separation (policy): {_art(n)} (rule {n['rule']}) is named by no entry of the policy; "
           f"{RULE}: every rule says what it may be fed (embodied_snap/lineage/policy.py)"
           for n in {n["rule"]: n for n in nodes if n["rule"] not in named}.values()]
    shards: dict[str, list[int]] = {}
    for i, n in enumerate(nodes):
        if n["rule"] in P.SOURCE_RULES and "shard" in n["wildcards"]:
            shards.setdefault(n["wildcards"]["shard"], []).append(i)
    for shard, starts in sorted(shards.items()):
        src = shard_source(shard)
        if src in P.POLICY:
            out += _walk(nodes, starts, src, f"{src} shard {shard}")
    n_direct = 0
    for i, n in enumerate(nodes):
        if n["rule"] in P.BOOKKEEPING:
            continue
        is_src = n["rule"] in P.SOURCE_RULES and "shard" in n["wildcards"]
        own = shard_source(n["wildcards"]["shard"]) if is_src else None  # already walked above
        first: dict[str, str] = {}  # source -> first group of it this job reads
        for f in n["input"]:
            g = group_of(f, raw)
            src = (groups or {}).get(g[0], {}).get("role") if g else None
            if src in P.POLICY and src != own:
                first.setdefault(src, g[0])
        for src, g in sorted(first.items()):
            n_direct += 1
            if not P.may_feed(src, n["rule"], n["wildcards"]):
                out.append(f"separation (DAG): {_art(n)} (rule {n['rule']}) reads raw {src} group {g}; "
                           f"{RULE}: {P.POLICY[src].rule}")
            else:
                out += _walk(nodes, [i], src, f"{src} group {g} (read by {P.label(n['rule'], n['wildcards'])})")
    # File sources: read directly only by their readers, then the usual walk.
    n_readers = 0
    for i, n in enumerate(nodes):
        for f in n["input"]:
            src = file_source(f, raw)
            if src is None:
                continue
            n_readers += src == "twin_truth"
            if n["rule"] not in P.POLICY[src].readers:
                out.append(f"separation (DAG): {_art(n)} (rule {n['rule']}) reads {f}; {RULE}: {P.POLICY[src].rule}")
            elif n["rule"] not in P.BOOKKEEPING:  # bookkeeping (the proof itself) passes no data on
                out += _walk(nodes, [i], src, f)
    return out, dict(dag_jobs=len(nodes), dag_source_shards=len(shards), dag_direct_readers=n_direct,
                     dag_truth_readers=n_readers)


def dag_uses(nodes: list[dict], groups: dict | None = None, raw: str = DEFAULT_RAW) -> dict[str, list[str]]:
    """Source -> the rules that consume its data on the DAG (Table I's "use"): the jobs that read
    its recordings, its resampled shards or the file itself, other than bookkeeping and gates."""
    stop = P.BOOKKEEPING | P.GATES | P.TARGETS
    through = P.SOURCE_RULES - P.BOOKKEEPING  # where data flows on unchanged (acquisition, resampling)
    starts: dict[str, set[int]] = {}
    for i, n in enumerate(nodes):
        if n["rule"] in through and "shard" in n["wildcards"]:
            starts.setdefault(shard_source(n["wildcards"]["shard"]), set()).add(i)
        if n["rule"] in stop or n["rule"] in through:
            continue
        for f in n["input"]:
            g = group_of(f, raw)
            src = (groups or {}).get(g[0], {}).get("role") if g else (
                file_source(f, raw) or (f if f in P.TARGET_FILES else None))
            if src:
                starts.setdefault(src, set()).add(i)
    out = {}
    for src, ids in starts.items():
        used, todo, seen = set(), deque(ids), set(ids)
        while todo:
            i = todo.popleft()
            rule = nodes[i]["rule"]
            if rule not in through:
                if rule not in stop:
                    used.add(rule)
                continue  # a consumer: what comes after it uses its result, not the source
            for k in nodes[i]["down"]:
                if k not in seen:
                    seen.add(k)
                    todo.append(k)
        out[src] = sorted(used)
    return dict(sorted(out.items()))


def _sentences() -> dict[str, str]:
    """Every source's rule: the policy's sentence, the disjointness of the target sets."""
    out = {k: s.rule for k, s in P.POLICY.items()}
    return {**out, **{f: TARGETS_RULE for f in P.TARGET_FILES if f not in P.POLICY}}


def by_source(violations: list[str]) -> tuple[dict[str, list[str]], list[str]]:
    """Each violation under the sources whose policy sentence (or target file) it names; the rest
    (an unnamed rule, an unreadable or missing record, a DAG that did not build) concern them all."""
    per: dict[str, list[str]] = {}
    rest = []
    for v in violations:
        hit = [k for k in _sentences() if _sentences()[k] in v or (k in P.TARGET_FILES and Path(k).name in v)]
        for k in hit:
            per.setdefault(k, []).append(v)
        if not hit:
            rest.append(v)
    return per, rest


# --- on the records --------------------------------------------------------------------------------


def _used(r: dict, raw: str) -> tuple[list[str], list[str]]:
    """A record's declared inputs, and the data files its job opened without declaring them (a job
    forced past its own check, records.check_declared): such a read feeds the job all the same."""
    ins = [e["path"] for e in r.get("inputs", [])]
    own = set(ins) | {e["path"] for e in r.get("outputs", [])} | set(r.get("log") or [])
    extra = [p for p in r.get("reads") or [] if p not in own and not p.startswith(RECORDS_DIR + "/")
             and (p.startswith("results/") or p.startswith(raw + "/"))]
    return ins, extra


def _record_violations(root: Path, groups: dict, raw: str, complete: bool) -> tuple[list[str], dict]:
    errors: list = []
    by_output = load_records(root, errors)
    out = [f"separation (records): {p} cannot be read ({why}); {RULE}: every result has a readable "
           "provenance record" for p, why in errors]
    recs = {r["_record"]: r for r in by_output.values()}
    fed: dict[str, dict[str, str]] = {}  # record -> {group or file source -> the source class}
    tainted: dict[str, set] = {}  # record -> sources already reported upstream
    missing: set[str] = set()

    def src_of(g):
        if g in P.POLICY:
            return g
        d = groups.get(g, {})
        # The sealed category is sealed whatever split.csv says (a wrong split is reported apart).
        return "sealed" if d.get("category") == "sealed" else (d.get("role") or "unknown")

    def visit(key, stack=()):
        if key in fed:
            return
        r = recs[key]
        f, v, t = {}, {}, set()  # sources fed, the direct input that carried each, sources reported
        ins, extra = _used(r, raw)
        for p in ins + extra:
            go, fs = group_of(p, raw), file_source(p, raw)
            if go or fs:
                g = go[0] if go else fs
                f.setdefault(g, src_of(g))
                v.setdefault(g, p)
                if fs:
                    t.add(fs)  # a direct read is judged by the readers check below, not again here
                continue
            prod = by_output.get(p)
            if prod is None:
                if complete and p.startswith("results/") and not p.startswith(RECORDS_DIR + "/"):
                    missing.add(f"separation (records): {p} (read by rule {r['rule']}) has no provenance "
                                f"record; {RULE}: every result has a readable provenance record")
                continue
            if prod["rule"] in P.BOOKKEEPING or prod["_record"] in stack:
                continue
            visit(prod["_record"], stack + (key,))
            for g, s in fed[prod["_record"]].items():
                f.setdefault(g, s)
                v.setdefault(g, p)
            t |= tainted[prod["_record"]]
        rule, wc = r["rule"], r.get("wildcards", {})
        by_src: dict[str, list[str]] = {}
        for g, s in f.items():
            by_src.setdefault(s, []).append(g)
        for s, gs in sorted(by_src.items()):
            if s not in t and not P.may_feed(s, rule, wc):
                gs = sorted(gs)
                more = f" (+{len(gs) - 1} more)" if len(gs) > 1 else ""
                what = gs[0] if s in P.POLICY and P.POLICY[s].readers else f"{s} group {gs[0]}{more}"
                out.append(f"separation (records): {_rart(r, key)} "
                           f"(rule {P.label(rule, wc)}) was fed by {what} through {v[gs[0]]}; "
                           f"{RULE}: {P.POLICY[s].rule}")
                t.add(s)
        fed[key], tainted[key] = f, t

    for key in sorted(recs):
        if recs[key]["rule"] not in P.BOOKKEEPING:
            visit(key)
    # Nothing but the readers reads a file source, bookkeeping included.
    for key, r in sorted(recs.items()):
        ins, extra = _used(r, raw)
        for p in ins + extra:
            src = file_source(p, raw)
            if src and r["rule"] not in P.POLICY[src].readers:
                out.append(f"separation (records): {_rart(r, key)} "
                           f"(rule {r['rule']}) read {p}; {RULE}: {P.POLICY[src].rule}")
        out += [f"separation (records): {_rart(r, key)} (rule {r['rule']}) read {p}, not among its declared "
                "inputs; rule: a job reads only what it declares" for p in extra]
    return out + sorted(missing), dict(records=len(recs))


def unrecorded(root: Path) -> list[str]:
    """Files under results/ that no record claims (a record deleted after the fact)."""
    claimed = set(load_records(root))
    out = []
    for f in sorted((root / "results").rglob("*")):
        p = f.relative_to(root).as_posix()
        # Snakemake's marker in a directory output is its own, not a result
        own = p.startswith(RECORDS_DIR + "/") or f.name == ".snakemake_timestamp" or p in AFTER_RUN
        if f.is_file() and not own and p not in claimed:
            out.append(
                f"separation (records): {p} has no provenance record; {RULE}: every result has "
                "a readable provenance record"
            )
    return out


def _split_violations(root: Path, groups: dict) -> list[str]:
    out = []
    if not (root / SPLIT_CSV).exists():
        return out
    for g, d in sorted(groups.items()):
        if d["category"] == "sealed" and d["evidence_set"] == "dynamics" and d["role"] in ("train", "validation"):
            out.append(
                f"separation (split): {SPLIT_CSV} puts sealed group {g} in {d['role']}; "
                f"{RULE}: {P.POLICY['sealed'].rule}"
            )
    return out


def _window_violations(root: Path, groups: dict) -> tuple[list[str], int]:
    out, n = [], 0
    for role in P.WINDOW_ROLES:
        p = root / f"results/splits/windows_{role}.npz"
        if not p.exists():
            continue
        n += 1
        with np.load(p, allow_pickle=False) as z:
            ids = sorted(set(str(x) for x in z["group_ids"])) if "group_ids" in z else None
        if ids is None:
            out.append(
                f"separation (windows): {p.relative_to(root)} has no group_ids array; "
                f"{RULE}: the window files must show which groups each model saw"
            )
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
            rule_of = P.POLICY[have].rule if have in P.POLICY else "windows of a role hold only groups of that role"
            more = f" (+{len(gs) - 1} more)" if len(gs) > 1 else ""
            out.append(
                f"separation (windows): {p.relative_to(root)} holds group {gs[0]}{more} of role "
                f"{have} ({SPLIT_CSV}); {RULE}: {rule_of}"
            )
    return out, n


def _target_violations(root: Path) -> tuple[list[str], dict[str, int]]:
    sets = {}
    for rel in P.TARGET_FILES:
        p = root / rel
        if p.exists():
            df = read_parquet(p)
            if "target_id" in df:
                sets[rel] = {str(x) for x in df["target_id"]}
            else:  # positions, rounded below any meaningful precision (1 nm)
                sets[rel] = {tuple(r) for r in df[["x", "y", "z"]].round(9).itertuples(index=False)}
    out = []
    names = sorted(sets)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            common = sets[a] & sets[b]
            if common:
                out.append(
                    f"separation (targets): {b} shares {len(common)} target(s) with "
                    f"{Path(a).name} (first: {sorted(common)[0]}); "
                    f"{RULE}: {TARGETS_RULE}"
                )
    return out, {k: len(v) for k, v in sorted(sets.items())}


MANIFEST = "results/deployment/manifest.json"


def deployment_violations(root: Path, raw: str) -> tuple[list[str], int]:
    """Nothing upstream of the manifest changed after export: its checksum holds, every input it
    hashed still has that hash, and every deployment trial ran this manifest (meta.json)."""
    rule = "docs/design.md 3: deployment runs the exported manifest; nothing upstream of it changes after export"
    if not (root / MANIFEST).exists():
        return [], 0
    try:
        man = load(root / MANIFEST)
    except ManifestError as e:
        return [f"separation (deployment): {e}; {rule}"], 0
    out = [f"separation (deployment): {MANIFEST}: {w}; {rule}" for w in inputs_changed(man, root)]
    groups = sorted((root / deployment_dir(raw) / "groups").glob("*/meta.json"))
    for m in groups:
        sha = json.loads(m.read_text()).get("manifest_sha256")
        if sha != man["checksum"]:
            out.append(f"separation (deployment): {m.relative_to(root)}: ran manifest {str(sha)[:12]}, "
                       f"not the exported {man['checksum'][:12]}; {rule}")
    return out, len(groups)


def _records_check(root: Path, raw: str, complete: bool) -> tuple[list[str], dict]:
    groups = load_groups(root, raw)
    out, counts = _record_violations(root, groups, raw, complete)
    if complete:
        out += unrecorded(root)
    out += _split_violations(root, groups)
    w, nw = _window_violations(root, groups)
    t, sizes = _target_violations(root)
    d, nd = deployment_violations(root, raw)
    counts.update(groups=len(groups), window_files=nw, target_sets=len(sizes), target_sizes=sizes,
                  deployment_trials=nd)
    return out + w + t + d, counts


def check_records(root=".", raw: str = DEFAULT_RAW, complete: bool = True) -> list[str]:
    return _records_check(Path(root), raw, complete)[0]


def check_dag(workdir=".", configfiles=None, config_overrides: dict | None = None, targets=("all",)) -> list[str]:
    raw = raw_dir_of(config_overrides)
    return dag_violations(build_dag(workdir, configfiles, config_overrides, targets), load_groups(workdir, raw), raw)[0]


def static_proof(root=".", config_overrides: dict | None = None, **dag_kwargs) -> dict:
    """The proof on the Snakemake DAG, for the config `config_overrides` (default: the one the last
    run recorded): {violations, checked, uses}. A DAG that cannot be built is a failed proof, not a
    pass."""
    root = Path(root)
    cfg = config_overrides if config_overrides is not None else (last_config(root) or {})
    raw = raw_dir_of(cfg)
    uses = {}
    try:
        wd = dag_kwargs.pop("workdir", root)
        nodes, groups = build_dag(wd, config_overrides=cfg, **dag_kwargs), load_groups(wd, raw)
        v, c = dag_violations(nodes, groups, raw)
        uses = dag_uses(nodes, groups, raw)
    except Exception as e:  # noqa: BLE001 -- any failure to build the DAG means no proof
        v, c = [f"separation (DAG): could not build the Snakemake DAG: {type(e).__name__}: {e}"], {}
    return dict(violations=v, checked=c, uses=uses)


def check(
    root=".", static=True, records=True, config_overrides: dict | None = None, complete: bool = True,
    dag: dict | None = None, **dag_kwargs
) -> dict:
    """Both proofs, for the config `config_overrides` (default: the one the last run recorded).
    `dag`: the DAG's proof already made (static_proof; the workflow's check_separation_dag job),
    else it is made here. `complete`: the run has finished, so every result file and every result a
    record used must have a record of its own (off inside the workflow, where jobs beside the check
    are still rebuilding theirs)."""
    root = Path(root)
    cfg = config_overrides if config_overrides is not None else (last_config(root) or {})
    raw = raw_dir_of(cfg)
    violations, checked, uses = [], {}, {}
    if static:
        s = dag if dag is not None else static_proof(root, cfg, **dag_kwargs)
        violations += s["violations"]
        checked.update(s["checked"])
        uses = s["uses"]
    if records:
        v, c = _records_check(root, raw, complete)
        violations += v
        checked.update(c)
    per, rest = by_source(violations)
    # What was proved for each source: its policy sentence, on which checks, and its violations.
    proofs = {k: dict(rule=rule, uses=uses.get(k, []), violations=per.get(k, []),
                      ok=not per.get(k) and not rest, dag=static, records=records)
              for k, rule in _sentences().items()}
    return dict(ok=not violations, violations=violations, checked=checked, raw_dir=raw, sources=proofs,
                unattributed=rest)

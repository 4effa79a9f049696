"""Table I from the lineage: one row per evidence set and simulated target set.

n is counted from the raw index (groups per evidence set), the split (groups per role of the
dynamics corpus) and the target files (targets per set, as the separation proof read them); `use`
is the rules that consume the data on the DAG and `separation` the sentence of the policy
(lineage/policy.py) that `esnap check-separation` proved for it, with its verdict. A source with a
violation, or a check that failed as a whole, reads "not proved": no row claims a separation that
was not proved.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pandas as pd

from ..lineage import policy as P
from ..lineage.groups import deployment_dir, load_groups
from . import html

COLUMNS = ("evidence", "domain", "n", "use", "separation", "verdict")
CORPUS = "dynamics"  # the evidence set the split divides into roles (P.WINDOW_ROLES)


def _verdict(proofs: list[dict]) -> str:
    bad = [v for p in proofs for v in p["violations"]]
    if bad:
        return f"not proved: {len(bad)} violation(s), first: {bad[0]}"
    if not all(p["ok"] for p in proofs):
        return "not proved: the separation check failed (see results/lineage/separation.json)"
    how = " and ".join(k for k in ("dag", "records") if all(p[k] for p in proofs))
    return f"proved ({how.replace('dag', 'DAG')})" if how else "not proved: no check ran"


def target_name(path: str) -> str:
    """A target file's row name: its set, after the folders below its stage that name a variant
    (results/robustness/uniform/targets_training.parquet -> "uniform training targets")."""
    parts = Path(path).parts
    return " ".join([*parts[2:-1], Path(path).stem.removeprefix("targets_"), "targets"])


def rows(sep: dict, root=".", simulated: bool = True) -> list[dict]:
    """sep: the separation proof (results/lineage/separation.json, lineage.checks.check)."""
    groups = load_groups(root, sep.get("raw_dir", "raw_data"))
    proofs = sep.get("sources", {})
    missing = dict(rule="", uses=[], violations=[], ok=False, dag=False, records=False)
    domain = "rig (simulated)" if simulated else "rig recordings"
    by_set: dict[str, int] = {}
    by_role: dict[str, int] = {}
    for d in groups.values():
        by_set[d["evidence_set"]] = by_set.get(d["evidence_set"], 0) + 1
        if d["evidence_set"] == CORPUS:
            by_role[d["role"]] = by_role.get(d["role"], 0) + 1
    # evidence sets in the policy's order, then any the policy does not know
    order = [k for k in P.POLICY if k in by_set] + sorted(set(by_set) - set(P.POLICY) - {CORPUS})
    out = []

    def row(name, dom, n, ps, sentence):
        uses = sorted({u for p in ps for u in p["uses"]})
        if not ps:
            ps = [missing]
        out.append(dict(evidence=name, domain=dom, n=n, use=", ".join(uses), separation=sentence,
                        verdict=_verdict(ps)))

    for es in order:
        if es in P.POLICY:
            p = proofs.get(es, missing)
            row(es, domain, by_set[es], [p], P.POLICY[es].rule)
    if CORPUS in by_set:
        roles = [r for r in P.WINDOW_ROLES if by_role.get(r)]
        split = ", ".join(f"{by_role[r]} {r}" for r in roles)
        row(f"{CORPUS} corpus", domain, by_set[CORPUS], [proofs.get(r, missing) for r in roles],
            f"group split: {split}")
        for r in roles:
            row(f"{CORPUS} {r}", domain, by_role[r], [proofs.get(r, missing)], P.POLICY[r].rule)
    for es in order:
        if es not in P.POLICY:  # an evidence set no policy row names: nothing was proved for it
            row(es, domain, by_set[es], [], "named by no policy entry")
    # the deployment trials: recorded after export into their own index (docs/deployment.md)
    dep = Path(root) / deployment_dir(sep.get("raw_dir", "raw_data")) / "index.csv"
    if dep.exists() and "deployment" in P.POLICY:
        with open(dep, newline="") as f:
            n = sum(1 for _ in csv.DictReader(f))
        row("deployment", domain, n, [proofs.get("deployment", missing)], P.POLICY["deployment"].rule)
    sizes = sep.get("checked", {}).get("target_sizes", {})
    for f in P.TARGET_FILES:
        if f in sizes:
            p = proofs.get(f, missing)
            row(target_name(f), "simulation", sizes[f], [p], P.POLICY[f].rule if f in P.POLICY else p["rule"])
    return out


def write(rows_: list[dict], base) -> list[Path]:
    """base.csv, base.md, base.tex and base.html (the report's view)."""
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    with open(base.with_suffix(".csv"), "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows_)
    df = pd.DataFrame([[str(r[c]) for c in COLUMNS] for r in rows_], columns=list(COLUMNS))
    md = df.map(lambda s: s.replace("|", "/")).rename(columns=str.capitalize)  # a | would split the cell
    base.with_suffix(".md").write_text(md.to_markdown(index=False, tablefmt="github", disable_numparse=True) + "\n")
    head = dict(zip(COLUMNS, ("Evidence", "Domain", "$n$", "Use", "Separation", "Verdict")))
    tex = df.rename(columns=head).style.hide(axis="index").format(escape="latex")
    cols = r"@{}p{0.13\textwidth}p{0.07\textwidth}rp{0.25\textwidth}p{0.3\textwidth}p{0.12\textwidth}@{}"
    base.with_suffix(".tex").write_text(tex.to_latex(column_format=cols, hrules=True))
    proved = sum(r["verdict"].startswith("proved") for r in rows_)
    base.with_suffix(".html").write_text(html.table(
        "Table I: evidence sets and their separation",
        f"{len(rows_)} rows; separation proved for {proved}, not proved for {len(rows_) - proved}.",
        COLUMNS, rows_, lambda r: "" if r["verdict"].startswith("proved") else "notproved"))
    return [base.with_suffix(e) for e in (".csv", ".md", ".tex", ".html")]

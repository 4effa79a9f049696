"""Which acquisition groups exist, and how they are sharded into jobs.

With the simulated rig the group list follows from the budget (deterministic, no data read);
with a real rig it is `raw_data/index.csv`. Both give the same table, so the DAG is built the
same way. Groups are processed in shards (fixed-size runs of one evidence set) because one job
per group would spend more time starting Python than working.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from .rawformat import CATEGORIES, EVIDENCE_SETS, PREFIX


class PlanError(ValueError):
    pass


def twin_plan(counts: dict, n_sessions: int) -> pd.DataFrame:
    """Group table for the simulated rig: ids `<prefix>_<nnnn>` numbered within an evidence set.

    Sessions are assigned round-robin within each evidence set so that every set spans the
    session-to-session variation.
    """
    rows = []
    for es in EVIDENCE_SETS:
        if es not in counts:
            continue
        n = 0
        for cat in CATEGORIES[es]:
            for _ in range(int(counts[es].get(cat, 0))):
                n += 1
                rows.append(
                    dict(
                        group_id=f"{PREFIX[es]}_{n:04d}",
                        evidence_set=es,
                        category=cat,
                        session=f"s{(n - 1) % n_sessions + 1:02d}",
                    )
                )
    return pd.DataFrame(rows, columns=["group_id", "evidence_set", "category", "session"])


def rig_plan(index_csv: str | Path) -> pd.DataFrame:
    """Group table of a real rig's recordings, with the checks that must hold to build a DAG."""
    index_csv = Path(index_csv)
    if not index_csv.exists():
        raise PlanError(f"{index_csv}: missing (rule: raw_data/index.csv lists every group)")
    df = pd.read_csv(index_csv, dtype=str)
    for col in ("group_id", "evidence_set", "category", "session"):
        if col not in df:
            raise PlanError(f"{index_csv}: column '{col}' missing (rule: index columns)")
    dup = df.group_id[df.group_id.duplicated()]
    if len(dup):
        raise PlanError(f"{index_csv}: group {dup.iloc[0]}: duplicate group_id (rule: unique group id)")
    bad = df[~df.evidence_set.isin(EVIDENCE_SETS)]
    if len(bad):
        r = bad.iloc[0]
        raise PlanError(
            f"{index_csv}: group {r.group_id}: unknown evidence set '{r.evidence_set}' (rule: evidence set)"
        )
    return df[["group_id", "evidence_set", "category", "session"]].reset_index(drop=True)


def assign_roles(groups: pd.DataFrame, n_validation: int, seed: int) -> pd.DataFrame:
    """Add `role`: the dynamics corpus is split by acquisition group (paper IV-A, 440/78/20).

    Sealed = the sealed category; `n_validation` of the rest are drawn with `seed`; the remainder
    trains. Other evidence sets get their own name as role. Depends on the group list alone, so
    changing a recording never moves a group between splits.
    """
    import numpy as np

    g = groups.copy()
    g["role"] = g.evidence_set
    dyn = g.evidence_set == "dynamics"
    g.loc[dyn, "role"] = "train"
    g.loc[dyn & (g.category == "sealed"), "role"] = "sealed"
    pool = g[dyn & (g.category != "sealed")].group_id.sort_values().to_numpy()
    if n_validation >= len(pool):
        raise PlanError(f"split: {n_validation} validation groups asked of {len(pool)} (rule: split sizes)")
    val = np.random.default_rng(seed).permutation(pool)[:n_validation]
    g.loc[g.group_id.isin(val), "role"] = "validation"
    return g


def shard(groups: pd.DataFrame, size: int) -> pd.DataFrame:
    """Add a `shard` column: `<evidence_set>-<kk>`, or `dynamics_<role>-<kk>` for the dynamics
    corpus, consecutive runs of `size` groups. Shards never mix splits, so the DAG itself shows
    which groups each model saw."""
    g = groups.copy()
    key = g.evidence_set.where(g.evidence_set != "dynamics", "dynamics_" + g.role)
    g["shard"] = ""
    for k, idx in g.groupby(key, sort=False).groups.items():
        ids = g.loc[idx].sort_values("group_id").index
        g.loc[ids, "shard"] = [f"{k}-{i // size:02d}" for i in range(len(ids))]
    return g.sort_values(["shard", "group_id"]).reset_index(drop=True)


def load_plan(config: dict, raw_dir: str | Path | None = None) -> pd.DataFrame:
    """The group table of this run: group_id, evidence_set, category, session, role, shard."""
    b = config["budgets"][config["budget"]]
    if config["raw_data"]["source"] == "twin":
        groups = twin_plan(b["groups"], config["sessions"])
    else:
        groups = rig_plan(Path(raw_dir or config["raw_data"]["dir"]) / "index.csv")
    groups = assign_roles(groups, b["split"]["validation"], config["seed"])
    return shard(groups, b["shard_size"])

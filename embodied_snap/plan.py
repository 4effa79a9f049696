"""Which acquisition groups exist, and how they are sharded into jobs.

With the simulated rig the group list follows from the budget (deterministic, no data read);
with a real rig it is `raw_data/index.csv`. Both give the same table, so the DAG is built the
same way. Groups are processed in shards (fixed-size runs of one evidence set) because one job
per group would spend more time starting Python than working.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from .rawformat import CATEGORIES, EVIDENCE_SETS, PREFIX, RecordingError


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


def rig_plan(index_csv: str | Path, pattern: str | None = None) -> pd.DataFrame:
    """Group table of a real rig's recordings: index.csv, with every check that must hold to
    build a DAG (readable, its columns, ids matching `pattern`, unique, known sets/categories)."""
    from .validate import GROUP_ID_PATTERN, read_index

    try:
        return read_index(Path(index_csv).parent, pattern or GROUP_ID_PATTERN)
    except RecordingError as e:
        raise PlanError(str(e)) from None


def assign_roles(groups: pd.DataFrame, n_validation: int, seed: int, split: bool = True) -> pd.DataFrame:
    """Add `role`: the dynamics corpus is split by acquisition group (paper IV-A, 440/78/20).

    Sealed = the sealed category; `n_validation` of the rest are drawn with `seed`; the remainder
    trains. Other evidence sets get their own name as role. Depends on the group list alone, so
    changing a recording never moves a group between splits. `split=False` (a partial corpus,
    `esnap validate --partial`): no split is drawn, since one drawn from part of the group list
    is not the run's; the sealed category is still `sealed`, the other dynamics groups keep
    `dynamics` as role, and the split-size rule does not apply.
    """
    import numpy as np

    g = groups.copy()
    g["role"] = g.evidence_set
    dyn = g.evidence_set == "dynamics"
    if not split:
        g.loc[dyn & (g.category == "sealed"), "role"] = "sealed"
        return g
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


def _twin_index_agrees(plan: pd.DataFrame, raw_dir: Path, pattern: str) -> None:
    """With the simulated rig the plan comes from the budget; an index.csv already written must
    list exactly those groups (a relabelled or extra row is not the rig's)."""
    if not (raw_dir / "index.csv").exists():
        return
    idx = rig_plan(raw_dir / "index.csv", pattern).set_index("group_id")
    path = raw_dir / "index.csv"
    for row in plan.itertuples():
        if row.group_id not in idx.index:
            raise PlanError(f"{path}: group {row.group_id}: no row (rule: index.csv matches the simulated rig's plan)")
        got = idx.loc[row.group_id]
        for k in ("evidence_set", "category", "session"):
            if got[k] != getattr(row, k):
                raise PlanError(f"{path}: group {row.group_id}: {k} '{got[k]}' but the plan says "
                                f"'{getattr(row, k)}' (rule: index.csv matches the simulated rig's plan)")
    extra = sorted(set(idx.index) - set(plan.group_id))
    if extra:
        raise PlanError(f"{path}: group {extra[0]}: not in the simulated rig's plan "
                        f"(rule: index.csv matches the simulated rig's plan)")


def exclusions(config: dict) -> dict[str, str]:
    """raw_data.exclude: group ids (a list) or id -> reason (a mapping), the user's decision."""
    ex = config["raw_data"].get("exclude") or {}
    if isinstance(ex, (list, tuple)):
        ex = {g: "raw_data.exclude" for g in ex}
    return {str(g): str(r) for g, r in ex.items()}


def load_plan(config: dict, raw_dir: str | Path | None = None, partial: bool = False) -> pd.DataFrame:
    """The group table of this run: group_id, evidence_set, category, session, role, shard.

    Checked before any DAG exists: index.csv (rig) or its agreement with the budget (twin),
    every folder under groups/ is a listed group, and excluded ids exist. Excluded groups keep
    their role and shard name (so no other group moves) and are then left out; the table's
    `attrs["excluded"]` says which, and why. `partial`: the tree is part of the corpus (`esnap
    validate --partial`): the same checks, but the dynamics corpus is not split (assign_roles).
    """
    from .validate import Limits, check_folders

    b = config["budgets"][config["budget"]]
    raw = Path(raw_dir or config["raw_data"]["dir"])
    pattern = Limits.from_config(config).group_id_pattern
    if config["raw_data"]["source"] == "twin":
        groups = twin_plan(b["groups"], config["sessions"])
        _twin_index_agrees(groups, raw, pattern)
    else:
        groups = rig_plan(raw / "index.csv", pattern)[["group_id", "evidence_set", "category", "session"]]
    try:
        check_folders(raw, groups.group_id)
    except RecordingError as e:
        raise PlanError(str(e)) from None
    excluded = exclusions(config)
    unknown = sorted(set(excluded) - set(groups.group_id))
    if unknown:
        raise PlanError(
            f"config raw_data.exclude: group {unknown[0]}: not a group of this run (rule: exclude names groups)"
        )
    groups = assign_roles(groups, b["split"]["validation"], config["seed"], split=not partial)
    plan = shard(groups, b["shard_size"])
    plan = plan[~plan.group_id.isin(list(excluded))].reset_index(drop=True)
    plan.attrs["excluded"] = excluded
    return plan

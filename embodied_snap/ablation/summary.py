"""Statistics of Fig. 6 and the claims: per release rule the mean S1 timing reward with its
target-family bootstrap interval, attachment at the reporting tolerance with Wilson intervals,
the fraction projected to a timing bound and the paired McNemar test against target-only release;
attachment over the tolerance sweep for the learned policy and the best fixed primitive."""

from __future__ import annotations

import pandas as pd

from ..policy.reward import attached
from . import stats as ST
from .release import REFERENCES, RULES


def _attach(df, r, d_f, v_min):
    return attached(df["lateral_m"].to_numpy(), df["gap_m"].to_numpy(), df["v_pk_mps"].to_numpy(), r, d_f, v_min)


def rules(df: pd.DataFrame, report_m: float, d_f: float, v_min: float, seed: int, n_boot: int) -> dict:
    out = {}
    base = df[df.rule == "target_only"].sort_values("target_id")
    a0 = _attach(base, report_m, d_f, v_min)
    for r in (*RULES, *REFERENCES):
        d = df[df.rule == r].sort_values("target_id")
        a = _attach(d, report_m, d_f, v_min)
        row = dict(n=int(len(d)), reward_mean=float(d["reward"].mean()),
                   reward_ci=ST.family_bootstrap(d["reward"].to_numpy(), d["family"].to_numpy(), seed, n_boot),
                   attachment=float(a.mean()), attachment_ci=ST.wilson(a.sum(), len(a)),
                   at_bound_fraction=float(d["at_bound"].mean()),
                   median_miss_mm=float(d["miss_m"].median() * 1e3))
        if r != "target_only":
            row["mcnemar"] = ST.mcnemar_p(a, a0)
        out[r] = row
    return out


def sweep(evals: dict[str, pd.DataFrame], tolerances, d_f: float, v_min: float) -> dict:
    return {"tolerances_m": list(tolerances),
            **{k: [float(_attach(df, r, d_f, v_min).mean()) for r in tolerances] for k, df in evals.items()}}

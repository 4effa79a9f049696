"""Architecture benchmark and generalisation (paper V-A, V-B, Fig. 5) from the policy-search results.

Inputs are the search's files, already loaded:
  runs   list of run dicts (results/policy/runs/{arch}_seed{seed}.json): curve, selection, theta
  evals  one DataFrame of every learned policy's evaluation rows (400 targets per arch and seed)
  fixed  the best fixed primitive's evaluation rows (arch "fixed", seed -1)
Everything here is a pure function; `summarize` gathers what the claims table and Fig. 5 need into
one JSON-able dict. Standard deviations are over seeds with ddof=1 (None for a single seed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.stats import mannwhitneyu

from .architectures import NAMES
from .reward import attached

ARCHS = NAMES  # plotting and table order: the architectures' table (architectures.py)
MATCHED = "centralised"  # the parameter-matched baseline (158 weights) that sets the reward level
REPORT_TOL_M = 0.05  # the paper's reporting tolerance (V-A): a protocol choice, not a result
AT_BOUND_S = 0.001  # "at a timing bound": within 1 ms of either end of T
SECTOR_DEG = 30.0
COMMANDS = ("rho1", "rho2", "rho3", "s3", "dphi_deg", "tau_s")


# ---------------------------------------------------------------------------- helpers


def _num(x):
    """A JSON-able float: NaN and inf become None."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _mean_sd(values) -> dict:
    v = np.asarray(values, float)
    return dict(
        mean=_num(v.mean()) if len(v) else None,
        sd=_num(v.std(ddof=1)) if len(v) > 1 else None,
        n=int(len(v)),
    )


def mann_whitney(a, b) -> dict:
    """Two-sided Mann-Whitney U over seeds (the paper's test for architecture rewards). scipy picks
    the exact distribution for small samples without ties: five vs five fully separated seeds give
    p = 2 / C(10, 5) = 0.0079."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if len(a) == 0 or len(b) == 0:
        return dict(u=None, p=None, n=[int(len(a)), int(len(b))])
    r = mannwhitneyu(a, b, alternative="two-sided")
    return dict(u=_num(r.statistic), p=_num(r.pvalue), n=[int(len(a)), int(len(b))])


def _archs(present) -> list[str]:
    present = set(present)
    return [a for a in ARCHS if a in present] + sorted(present - set(ARCHS))


# ---------------------------------------------------------------------------- Eq. 11


def attachment(df: pd.DataFrame, r: float, d_f: float, v_min: float) -> pd.Series:
    """Eq. 11 (`reward.attached`), one bool per evaluation row."""
    return pd.Series(attached(df.lateral_m.to_numpy(), df.gap_m.to_numpy(), df.v_pk_mps.to_numpy(), r, d_f, v_min),
                     index=df.index)


def attachment_rates(evals: pd.DataFrame, tolerances, d_f: float, v_min: float) -> pd.DataFrame:
    """Attachment rate of every (arch, seed) at every lateral tolerance: columns arch, seed,
    tolerance_m, rate, n_targets."""
    rows = []
    for (arch, seed), g in evals.groupby(["arch", "seed"], sort=True):
        for r in tolerances:
            rows.append(dict(arch=arch, seed=int(seed), tolerance_m=float(r),
                             rate=float(attachment(g, r, d_f, v_min).mean()), n_targets=len(g)))
    return pd.DataFrame(rows)


def attachment_table(rates: pd.DataFrame) -> pd.DataFrame:
    """Mean and SD over seeds per arch and tolerance (the fixed primitive is its own row, n_seeds 1)."""
    t = rates.groupby(["arch", "tolerance_m"]).rate.agg(mean="mean", sd=lambda v: v.std(ddof=1), n_seeds="count")
    return t.reset_index()


# ---------------------------------------------------------------------------- reward and efficiency


def final_rewards(runs: list[dict]) -> dict:
    """arch -> {seed: final held-out reward} (the curve's last value)."""
    out: dict = {}
    for run in runs:
        out.setdefault(run["arch"], {})[int(run["seed"])] = float(run["final_heldout_reward"])
    return {a: dict(sorted(out[a].items())) for a in _archs(out)}


def evaluations_to_reach(curve: list[dict], level: float):
    """Cumulative simulator evaluations at the first generation whose held-out reward reaches
    `level`; None if the curve never does (a "failure", drawn as a cross at the budget)."""
    for point in sorted(curve, key=lambda p: p["generation"]):
        if point["heldout_reward"] >= level:
            return int(point["evaluations"])
    return None


def reach(runs: list[dict], budget_evaluations: int, level_arch: str = MATCHED) -> dict:
    """Fig. 5c: level = mean final held-out reward of the matched centralised seeds; per arch the
    evaluations each seed needs to reach it, how many do, and the median over those that do."""
    finals = final_rewards(runs)
    level = float(np.mean(list(finals[level_arch].values()))) if finals.get(level_arch) else None
    per_arch = {}
    for arch in finals:
        per_seed = {int(r["seed"]): (evaluations_to_reach(r["curve"], level) if level is not None else None)
                    for r in sorted(runs, key=lambda r: r["seed"]) if r["arch"] == arch}
        hit = [v for v in per_seed.values() if v is not None]
        med = float(np.median(hit)) if hit else None
        per_arch[arch] = dict(
            n_seeds=len(per_seed),
            n_reached=len(hit),
            median_evaluations=med,
            median_pct_budget=100.0 * med / budget_evaluations if med is not None else None,
            per_seed={str(s): v for s, v in per_seed.items()},
        )
    return dict(level=level, level_arch=level_arch, budget_evaluations=int(budget_evaluations), per_arch=per_arch)


def curve_bands(runs: list[dict]) -> dict:
    """Fig. 5a: per arch the held-out reward over evaluations, mean and min-max over seeds. Seeds of
    one arch share the evaluation grid; only generations every seed has are kept."""
    out = {}
    for arch in _archs({r["arch"] for r in runs}):
        table = pd.DataFrame(
            {r["seed"]: pd.Series({p["evaluations"]: p["heldout_reward"] for p in r["curve"]})
             for r in runs if r["arch"] == arch}
        ).sort_index().dropna()
        out[arch] = dict(
            evaluations=[int(e) for e in table.index],
            mean=table.mean(axis=1).tolist(),
            min=table.min(axis=1).tolist(),
            max=table.max(axis=1).tolist(),
            n_seeds=int(table.shape[1]),
        )
    return out


# ---------------------------------------------------------------------------- selected shared policy (V-A)


def selected_seed(runs: list[dict], arch: str = "shared") -> int:
    """The selected policy: the seed with the highest reward on the 64 selection targets (never the
    400 evaluation targets, which would select on the test set)."""
    return int(max((r for r in runs if r["arch"] == arch), key=lambda r: r["selection_reward"])["seed"])


def closest_approach_mm(df: pd.DataFrame) -> list[float]:
    """25th, 50th, 75th percentile of the closest-approach distance (numpy's linear interpolation)."""
    return [float(v) for v in np.percentile(df.miss_m.to_numpy() * 1e3, [25, 50, 75])]


def command_ranges(df: pd.DataFrame) -> dict:
    """5th-95th percentile (and min-max) of each selected command over the evaluation targets."""
    return {c: dict(p5=float(np.percentile(df[c], 5)), p95=float(np.percentile(df[c], 95)),
                    min=float(df[c].min()), max=float(df[c].max())) for c in COMMANDS}


def _pearson(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 3 or x.std() == 0 or y.std() == 0:
        return None
    return _num(np.corrcoef(x, y)[0, 1])


def correlations(df: pd.DataFrame) -> dict:
    """Pearson r of commands with target features (V-A). Height is e_m itself: the target's vertical
    coordinate relative to the base (Y up). The arm hangs down, so e < 0 and a higher target has a
    less negative e; a positive r means the command grows as the target rises."""
    return dict(
        rho3_height=_pearson(df.rho3, df.e_m),
        rho3_distance=_pearson(df.rho3, df.d_m),
        rho2_distance=_pearson(df.rho2, df.d_m),
        dphi_height=_pearson(df.dphi_deg, df.e_m),
        tau_distance=_pearson(df.tau_s, df.d_m),
        # the paper's "distance" read as the horizontal radius r, and how d and height go together
        # over the targets (on the arm's reach shell d falls as the target rises: docs/policy.md)
        rho3_radius=_pearson(df.rho3, df.r_m),
        rho2_radius=_pearson(df.rho2, df.r_m),
        tau_radius=_pearson(df.tau_s, df.r_m),
        targets_distance_height=_pearson(df.d_m, df.e_m),
    )


def at_timing_bound(tau, bounds, within=AT_BOUND_S) -> float:
    """Fraction of release times within `within` s of either end of the timing set `bounds` (the
    hardware-validated release interval T of Eq. 8, the protocol's)."""
    tau = np.asarray(tau, float)
    return float(((np.abs(tau - bounds[0]) <= within) | (np.abs(tau - bounds[1]) <= within)).mean())


def _unwrap(bearing_deg):
    """Bearings as a continuous arc: relative to their circular mean, so an arc across 0/360 stays
    in one piece."""
    b = np.radians(np.asarray(bearing_deg, float))
    centre = np.degrees(np.arctan2(np.sin(b).mean(), np.cos(b).mean()))
    # rounded so that the trip through radians does not move a bearing across a sector edge
    return np.round(centre + (np.degrees(b) - centre + 180.0) % 360.0 - 180.0, 9)


def bearing_arc_deg(df: pd.DataFrame) -> float:
    u = _unwrap(df.bearing_deg)
    return float(u.max() - u.min())


def miss_by_sector(df: pd.DataFrame, width: float = SECTOR_DEG) -> list[dict]:
    """Median miss per bearing sector of `width` degrees, starting at the smallest evaluated bearing.
    The number of sectors is the arc over the width, rounded (180 deg -> 6); the last sector takes
    the remainder, so the targets at the far end of the arc are not a sector of their own."""
    u = _unwrap(df.bearing_deg)
    lo = u.min()
    n = max(1, round((u.max() - lo) / width))
    k = np.clip(np.floor((u - lo) / width).astype(int), 0, n - 1)
    out = []
    for i in range(n):
        m = df.miss_m.to_numpy()[k == i]
        out.append(dict(lo_deg=float((lo + i * width) % 360), hi_deg=float((lo + (i + 1) * width) % 360), n=int(len(m)),
                        median_miss_mm=_num(np.median(m) * 1e3) if len(m) else None))
    return out


def miss_by_distance(df: pd.DataFrame, bins: int = 6) -> list[dict]:
    """Median miss in equal-count distance bins (as many as bearing sectors), to compare with the
    sector spread: the paper finds miss varies "more strongly with target distance"."""
    q = pd.qcut(df.d_m, bins, duplicates="drop")
    return [dict(lo_m=float(iv.left), hi_m=float(iv.right), n=int(len(g)),
                 median_miss_mm=float(g.miss_m.median() * 1e3))
            for iv, g in df.groupby(q, observed=True)]


def _spread(rows):
    v = [r["median_miss_mm"] for r in rows if r["median_miss_mm"] is not None]
    return [min(v), max(v)] if v else None


def policy_stats(df: pd.DataFrame, report_m: float, d_f: float, v_min: float, detail: bool = False,
                 timing_s=None) -> dict:
    """V-A statistics of one policy on the evaluation targets; `detail` adds the commands, their
    correlations, the share of release times at a bound of the timing set timing_s and the miss
    per bearing sector (for the selected shared policy)."""
    out = dict(
        n_targets=int(len(df)),
        arc_deg=bearing_arc_deg(df),
        closest_approach_mm=closest_approach_mm(df),
        attachment=float(attachment(df, report_m, d_f, v_min).mean()),
        speed_fraction=float((df.v_pk_mps >= v_min).mean()),
    )
    if detail:
        sectors, distance = miss_by_sector(df), miss_by_distance(df)
        out.update(
            commands=command_ranges(df),
            correlations=correlations(df),
            tau_at_bound_fraction=at_timing_bound(df.tau_s, timing_s),
            sectors=sectors,
            sector_median_range_mm=_spread(sectors),
            distance_bins=distance,
            distance_median_range_mm=_spread(distance),
        )
    return out


# ---------------------------------------------------------------------------- everything


@dataclass(frozen=True)
class SummaryCriteria:
    """What the evaluation rows are read by: Eq. 11's attachment, its tolerances and the timing set."""

    tolerances: list  # lateral tolerances of the attachment sweep (m), config policy.tolerances_m
    d_f: float  # Eq. 11: the largest |gap| to the target's plane that attaches (m)
    v_min: float  # Eq. 11: the least peak speed that attaches in the simulator (m/s)
    timing_s: tuple  # the timing set T of Eq. 8 (the protocol's)
    report_m: float = REPORT_TOL_M  # the reporting tolerance (V-A)


def summarize(runs: list[dict], evals: pd.DataFrame, fixed: pd.DataFrame, budget_evaluations: int,
              criteria: SummaryCriteria) -> dict:
    """The one dict behind results/policy/summary.json, Fig. 5 and results/policy/claims.csv."""
    d_f, v_min, timing_s, report_m = criteria.d_f, criteria.v_min, criteria.timing_s, criteria.report_m
    tolerances = [float(t) for t in criteria.tolerances]
    archs = _archs({r["arch"] for r in runs})
    finals = final_rewards(runs)

    # (b) attachment over the tolerance sweep, learned seeds and the fixed primitive alike
    rates = attachment_rates(pd.concat([evals, fixed], ignore_index=True), tolerances, d_f, v_min)
    table = attachment_table(rates)
    sweep = {}
    for arch, g in table.groupby("arch"):
        g = g.sort_values("tolerance_m")
        sweep[arch] = dict(mean=[_num(v) for v in g["mean"]], sd=[_num(v) for v in g["sd"]],
                           n_seeds=int(g.n_seeds.max()))

    # attachment at the reporting tolerance, per seed (computed directly: no float lookup in the sweep)
    at_report = {}
    for (arch, seed), g in pd.concat([evals, fixed]).groupby(["arch", "seed"], sort=True):
        at_report.setdefault(arch, {})[str(int(seed))] = float(attachment(g, report_m, d_f, v_min).mean())
    attach_report = {a: dict(_mean_sd(list(v.values())), per_seed=v) for a, v in at_report.items()}

    other = [a for a in archs if a != "shared"]
    shared_r = list(finals.get("shared", {}).values())
    shared_a = list(at_report.get("shared", {}).values())

    # V-A: the selected shared policy against the best fixed primitive
    sel = selected_seed(runs) if "shared" in finals else None
    sel_reward = next((float(r["selection_reward"]) for r in runs if r["arch"] == "shared" and r["seed"] == sel), None)
    sel_evals = evals[(evals.arch == "shared") & (evals.seed == sel)]
    best_c = max(at_report.get(MATCHED, {}).items(), key=lambda kv: kv[1], default=(None, None))

    return dict(
        archs=archs,
        budget_evaluations=int(budget_evaluations),
        report_tolerance_m=float(report_m),
        d_f_m=float(d_f),
        v_min_sim_mps=float(v_min),
        n_params={a: int(next(r["n_params"] for r in runs if r["arch"] == a)) for a in archs},
        evaluations_per_generation={
            a: int(next(r["evaluations_per_generation"] for r in runs if r["arch"] == a)) for a in archs
        },
        seeds={a: [int(x) for x in finals[a]] for a in archs},
        reward={
            a: dict(_mean_sd(list(finals[a].values())), per_seed={str(k): v for k, v in finals[a].items()})
            for a in archs
        },
        reward_tests={a: mann_whitney(shared_r, list(finals[a].values())) for a in other},
        curves=curve_bands(runs),
        attachment_sweep=dict(tolerances_m=tolerances, archs=sweep),
        attachment_report=attach_report,
        attachment_tests={a: mann_whitney(shared_a, list(at_report.get(a, {}).values())) for a in other},
        attachment_tests_sweep={  # shared vs matched centralised at every tolerance
            f"{r:g}": mann_whitney(
                rates[(rates.arch == "shared") & (rates.tolerance_m == r)].rate,
                rates[(rates.arch == MATCHED) & (rates.tolerance_m == r)].rate,
            )
            for r in tolerances
        },
        reach=reach(runs, budget_evaluations) if MATCHED in finals else None,
        selected=dict(
            arch="shared",
            seed=sel,
            selection_reward=sel_reward,
            **policy_stats(sel_evals, report_m, d_f, v_min, detail=True, timing_s=timing_s),
        )
        if sel is not None
        else None,
        fixed=policy_stats(fixed, report_m, d_f, v_min),
        best_centralised=dict(seed=None if best_c[0] is None else int(best_c[0]), attachment=best_c[1]),
    )

"""Does the architecture ranking depend on where the search starts? (docs/policy.md, "Starting point")

The benchmark's searches run again from other starts (`networks.initial`, config
`policy.sensitivity`); each start is summarised by `robustness.variant`, as the benchmark is, and
read by the rule docs/policy.md fixed before the first run: the paper's ordering is reproduced under
a start when shared's mean final held-out reward is above the matched centralised controller's with
a two-sided Mann-Whitney p < ALPHA. The slope probe says how tied a policy's three sections are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..reference import fmt
from .analysis import MATCHED, SummaryCriteria
from .networks import ACTIONS, initial, outputs
from .robustness import variant
from .search import normalised

ALPHA = 0.05  # the reading's significance level (docs/policy.md), fixed before the first run
PRELOADS = tuple(ACTIONS.index(f"rho{i}") for i in (1, 2, 3))  # the sections' preload outputs
PAIRS = ((0, 1), (0, 2), (1, 2))
EPS = 1e-4  # central-difference step in normalised feature units


def slopes(arch: str, theta, g: np.ndarray) -> np.ndarray:
    """(3 sections, 3 features): the mean slope of each section's preload output u_rho_i with respect
    to the normalised target features g (N, 3), by central differences at every target."""
    out = np.empty((3, g.shape[1]))
    for k in range(g.shape[1]):
        step = np.zeros(g.shape[1])
        step[k] = EPS
        du = (outputs(arch, theta, g + step) - outputs(arch, theta, g - step)) / (2 * EPS)
        out[:, k] = du[:, PRELOADS].mean(0)
    return out


def _cos(a, b):
    n = np.linalg.norm(a) * np.linalg.norm(b)
    return float(a @ b / n) if n > 0 else None


def probe(arch: str, theta, g: np.ndarray) -> dict:
    """The slope probe of one policy: the cosine of each pair of sections' slope vectors (1 = the
    three sections move their preloads alike with the target), their mean, and the weight norm."""
    s = slopes(arch, np.asarray(theta, float), g)
    cos = {f"s{i + 1}s{j + 1}": _cos(s[i], s[j]) for i, j in PAIRS}
    valid = [c for c in cos.values() if c is not None]
    return dict(cosine=cos, cosine_mean=float(np.mean(valid)) if valid else None,
                weight_norm=float(np.linalg.norm(theta)))


def reproduced(summary: dict) -> bool | None:
    """The reading: shared above centralised (means) with p < ALPHA; None without both."""
    r, t = summary["reward"], summary["reward_tests"].get(MATCHED)
    if "shared" not in r or MATCHED not in r or t is None or t["p"] is None:
        return None
    return bool(r["shared"]["mean"] > r[MATCHED]["mean"] and t["p"] < ALPHA)


def start_probe(arch: str, start: dict, g: np.ndarray, seeds, draws: int, rng) -> float | None:
    """How tied the sections are where a search begins: the mean slope cosine of `draws` CMA-ES first
    candidates, theta = start + sigma0 N(0, I), over the runs' seeds (g: normalised features)."""
    cos = []
    for s in seeds:
        x0 = initial(arch, start, s)
        for _ in range(draws):
            c = probe(arch, x0 + start["sigma0"] * rng.standard_normal(len(x0)), g)["cosine_mean"]
            cos += [] if c is None else [c]
    return float(np.mean(cos)) if cos else None


@dataclass(frozen=True)
class ProbeSpec:
    """What the slope probes read."""

    features: np.ndarray  # the evaluation targets' raw features (N, 3), normalised per run by its training statistics
    seed: int  # seed of the start probe's draws
    draws: int = 8  # first candidates the start probe draws per run's seed


def summarize_starts(starts: dict, runs_of: dict, evals_of: dict, fixed, budget_evaluations: int,
                     criteria: SummaryCriteria, probe_spec: ProbeSpec) -> dict:
    """starts: name -> its start (the benchmark's first); runs_of / evals_of: name -> its runs and
    evaluation rows; fixed: the fixed primitive's evaluation rows."""
    features = probe_spec.features
    out = {}
    for name, start in starts.items():
        runs = sorted(runs_of[name], key=lambda r: (r["arch"], r["seed"]))
        summary = variant(runs, evals_of[name], fixed, budget_evaluations, criteria)
        summary["start"] = {k: v for k, v in start.items() if k != "archs"}
        summary["reproduced"] = reproduced(summary)
        summary["probe"], summary["start_probe"], first = {}, {}, {}
        for run in runs:
            g = normalised(features, run["norm"])
            first.setdefault(run["arch"], g)
            summary["probe"].setdefault(run["arch"], {})[str(run["seed"])] = probe(run["arch"], run["theta"], g)
        for arch in summary["archs"]:
            rng = np.random.default_rng(probe_spec.seed)
            summary["start_probe"][arch] = start_probe(arch, summary["start"], first[arch], summary["seeds"][arch],
                                                       probe_spec.draws, rng)
        out[name] = summary
    return out


def claim_rows(summary: dict) -> list[dict]:
    """Rows of results/sensitivity/starts.csv: per start the reward per architecture, the reading,
    the budget share to reach the centralised level, and the slope probe of the selected policies.
    The paper has no such table: the reference column is empty."""
    rows = []
    for name, x in summary.items():
        def row(cid, quantity, ours, unit="", name=name):
            rows.append(dict(claim_id=f"{name}.{cid}", start=name, section="V-B", quantity=quantity, paper="",
                             ours=fmt(ours), unit=unit))

        st = x["start"]
        row("start", "weights at the start, CMA-ES sigma0", f"{st['init']}, {st['sigma0']:g}")
        for a in x["archs"]:
            r = x["reward"][a]
            row(f"reward_{a}", f"final held-out reward, {a}: mean, sd over {r['n']} seeds", [r["mean"], r["sd"]],
                "reward")
        for a, t in x["reward_tests"].items():
            row(f"reward_p_shared_vs_{a}", f"final reward, shared vs {a}: two-sided Mann-Whitney p", t["p"], "p")
        row("reproduced", f"paper's ordering reproduced (shared > {MATCHED}, p < {ALPHA:g})",
            {True: "yes", False: "no", None: "n/a"}[x["reproduced"]])
        reach = (x.get("reach") or {}).get("per_arch", {})
        for a, q in reach.items():
            row(f"reach_{a}", f"{a}: seeds reaching the {MATCHED} level, median share of the budget",
                [f"{q['n_reached']}/{q['n_seeds']}", None if q["median_pct_budget"] is None
                 else q["median_pct_budget"] / 100], "fraction")
        for a, c in x["start_probe"].items():
            row(f"start_cosine_{a}", f"{a} at the start (first candidates): mean slope cosine of the sections' "
                "preloads", c, "cosine")
        for a, per in x["probe"].items():
            cos = [p["cosine_mean"] for p in per.values() if p["cosine_mean"] is not None]
            norm = [p["weight_norm"] for p in per.values()]
            row(f"slope_cosine_{a}", f"selected {a} policies: mean slope cosine of the sections' preloads, "
                "mean and range over seeds", [float(np.mean(cos)), min(cos), max(cos)] if cos else None, "cosine")
            row(f"weight_norm_{a}", f"selected {a} policies: weight norm, mean and range over seeds",
                [float(np.mean(norm)), min(norm), max(norm)], "")
    return rows

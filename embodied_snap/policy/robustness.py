"""Is the architecture ranking robust? (docs/policy.md, "Robustness"; paper V-B asks of the benchmark)

The benchmark (rules/policy.smk) and its variants are each summarised by `analysis.summarize`, the
function behind Fig. 5 and results/policy/claims.csv; this module ranks the four architectures in each
and says whether the ranking is the benchmark's. Variants: "uniform" (targets drawn uniformly over
the measured workspace), and one per evaluation budget factor (a smaller budget is the selection
each run had made at that point, `search.at_budget`; a larger one the runs continued).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..reference import fmt
from .analysis import ARCHS, SummaryCriteria, summarize
from .search import at_budget

BENCHMARK = "benchmark"
KEEP = ("archs", "budget_evaluations", "seeds", "reward", "reward_tests", "attachment_report", "attachment_tests",
        "reach")


def ranking(means: dict, tie: float = 1e-9) -> list[str]:
    """Architectures by mean, best first; equal means (within `tie`) share a place, "a = b"."""
    order = sorted((a for a in means if means[a] is not None), key=lambda a: -means[a])
    places: list[list[str]] = []
    for a in order:
        if places and abs(means[places[-1][0]] - means[a]) <= tie:
            places[-1].append(a)
        else:
            places.append([a])
    return [" = ".join(sorted(p, key=order.index)) for p in places]


def variant(runs, evals, fixed, budget_evaluations: int, criteria: SummaryCriteria) -> dict:
    """One variant: the benchmark's statistics, then its rankings by final held-out reward and by
    attachment at the reporting tolerance."""
    summary = summarize(runs, evals, fixed, budget_evaluations, criteria)
    out = {k: summary[k] for k in KEEP}
    selected = summary["selected"]
    out["selected"] = {k: selected[k] for k in ("seed", "attachment", "correlations")} if selected else None
    out["ranking_reward"] = ranking({a: r["mean"] for a, r in summary["reward"].items()})
    out["ranking_attachment"] = ranking({a: r["mean"] for a, r in summary["attachment_report"].items()
                                         if a != "fixed"})
    return out


@dataclass(frozen=True)
class VariantBudgets:
    """Each variant's search budget."""

    generations: int  # the benchmark's CMA-ES generations, and every variant's without its own
    budget_generations: dict  # variant -> its generations, for the budget variants
    evaluations_per_generation: int  # simulator evaluations per generation (popsize x training targets)


def summarize_variants(benchmark_runs, runs_of: dict, evals_of: dict, fixed_of: dict, budgets: VariantBudgets,
                       criteria: SummaryCriteria) -> dict:
    """runs_of / evals_of / fixed_of: variant -> its runs, evaluation rows and fixed-primitive rows, the
    benchmark first (runs_of lacks the smaller budgets: those are the benchmark's runs at their
    snapshot)."""
    out = {}
    for name in evals_of:
        gens = budgets.budget_generations.get(name, budgets.generations)
        runs = runs_of.get(name) or [at_budget(r, gens) for r in benchmark_runs]
        out[name] = variant(runs, evals_of[name], fixed_of[name], gens * budgets.evaluations_per_generation, criteria)
        out[name]["generations"] = gens
    ref = out[BENCHMARK]
    for summary in out.values():
        summary["ranking_reward_holds"] = summary["ranking_reward"] == ref["ranking_reward"]
        summary["ranking_attachment_holds"] = summary["ranking_attachment"] == ref["ranking_attachment"]
    return out


def claim_rows(summary: dict, paper: dict) -> list[dict]:
    """Rows of results/robustness/variants.csv: each variant's architecture result. paper: the policy
    section's paper column (reference.paper_column("policy")); the variants are not in the paper, so the reference
    column is the paper's benchmark (its rankings derived from its values, where it gives them)."""
    def ref(key):
        return paper.get(key)

    def pair(key):
        return None if ref(f"{key}_mean") is None else [ref(f"{key}_mean"), ref(f"{key}_sd")]

    def ref_ranking(key):
        means = {a: ref(f"{key}_{a}_mean") for a in ARCHS}
        return " > ".join(ranking({a: m for a, m in means.items() if m is not None}))

    rows = []
    for v, x in summary.items():
        def row(cid, quantity, ours, ref_value, unit="", v=v):
            rows.append(dict(claim_id=f"{v}.{cid}", variant=v, section="V-B", quantity=quantity,
                             paper=fmt(ref_value), ours=fmt(ours), unit=unit))

        row("generations", "CMA-ES generations (x popsize x targets = the evaluation budget)", x["generations"],
            None)
        for a in x["archs"]:
            r, t = x["reward"][a], x["attachment_report"].get(a, {})
            row(f"reward_{a}", f"final held-out reward, {a}: mean, sd over {r['n']} seeds", [r["mean"], r["sd"]],
                pair(f"reward_{a}"), "reward")
            row(f"attach_5cm_{a}", f"simulated attachment at 5 cm, {a}: mean, sd over seeds",
                [t.get("mean"), t.get("sd")], pair(f"attach_5cm_{a}"), "fraction")
        for a, t in x["reward_tests"].items():
            row(f"reward_p_shared_vs_{a}", f"final reward, shared vs {a}: two-sided Mann-Whitney p", t["p"],
                ref(f"reward_p_shared_vs_{a}"), "p")
        row("ranking_reward", "architectures by final held-out reward", " > ".join(x["ranking_reward"]),
            ref_ranking("reward"))
        row("ranking_attach_5cm", "architectures by attachment at 5 cm", " > ".join(x["ranking_attachment"]),
            ref_ranking("attach_5cm"))
        row("ranking_reward_holds", "ranking by reward is the benchmark's",
            "yes" if x["ranking_reward_holds"] else "no", None)
        row("ranking_attach_5cm_holds", "ranking by attachment is the benchmark's",
            "yes" if x["ranking_attachment_holds"] else "no", None)
    return rows

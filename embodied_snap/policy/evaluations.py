"""The policy search's evaluation budget (paper V-A), written once: a CMA-ES generation rolls out
each of its popsize candidates on its targets_per_candidate training targets.

Imported by the rule files (it imports nothing), and by the search itself.
"""


def evaluations(generations: int, popsize: int, targets_per_candidate: int) -> int:
    """Simulator evaluations of `generations` generations: the x-axis of Fig. 5a and the budget
    that the evaluations to reach a level are a share of."""
    return generations * popsize * targets_per_candidate


def training_targets(generations: int, targets_per_candidate: int) -> int:
    """Training targets `generations` generations draw: a fresh set per generation."""
    return generations * targets_per_candidate

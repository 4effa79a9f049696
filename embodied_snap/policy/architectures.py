"""The policy architectures of paper IV-B/IV-C: the one table that names them (docs/policy.md).

One row per architecture, in plotting and table order (Fig. 5, results/policy/claims.csv): its name
(the `arch` of runs, rules and config), the layer sizes of each of its networks, how the three
sections share them, its label and its colour (an index into figures.style.PALETTE). Everything
else (networks, analysis, claims, Fig. 5, the config check of `budgets.*.policy.seeds`) iterates
this table; adding an architecture is one row here and its seed counts in config.yaml.

Sharing modes (`networks.outputs`):
  section_code  one network evaluated once per section on [g_norm, one-hot section]; section i
                keeps its first SECTION_OUTPUTS[i] outputs (rho1, dphi, tau | rho2 | rho3, s3)
  joint         one network on g_norm giving all six outputs
  per_section   one network per section on g_norm, section i giving SECTION_OUTPUTS[i] outputs
"""

from __future__ import annotations

from typing import NamedTuple

SECTION_OUTPUTS = (3, 1, 2)  # outputs of S1, S2, S3 in ACTIONS order (rho1, dphi, tau | rho2 | rho3, s3)
SHARING = ("section_code", "joint", "per_section")


def mlp_sizes(n_in: int, width: int, n_out: int) -> list[tuple[int, int]]:
    """(out, in) of each layer of an n_in-width-width-n_out tanh network."""
    return [(width, n_in), (width, width), (n_out, width)]


class Architecture(NamedTuple):
    name: str
    nets: list  # per network, its layers' (out, in)
    sharing: str  # one of SHARING
    label: str  # Fig. 5's name for it
    colour: int  # index into figures.style.PALETTE


TABLE = (
    Architecture("shared", [mlp_sizes(6, 8, 3)], "section_code", "Shared", 0),
    Architecture("centralised", [mlp_sizes(3, 8, 6)], "joint", "Centralised", 1),
    Architecture("centralised16", [mlp_sizes(3, 16, 6)], "joint", "Centralised-16", 2),
    Architecture("unshared", [mlp_sizes(3, 8, 3), mlp_sizes(3, 8, 1), mlp_sizes(3, 8, 2)], "per_section",
                 "Unshared", 3),
)
BY_NAME = {a.name: a for a in TABLE}
NAMES = tuple(BY_NAME)  # plotting and table order


def seeds_error(config: dict) -> str | None:
    """One line naming the budget's `policy.seeds` key that is not an architecture of TABLE, or the
    architecture it lacks (as the schema's errors read); None if every budget names exactly TABLE."""
    for b, spec in config["budgets"].items():
        where = f"config: budgets.{b}.policy.seeds"
        seeds = spec["policy"]["seeds"]
        for k in seeds:
            if k not in BY_NAME:
                return (f"{where}: {k!r} is not an architecture (known: {', '.join(NAMES)}; "
                        f"embodied_snap/policy/architectures.py)")
        for k in NAMES:
            if k not in seeds:
                return (f"{where}: {k!r} is a required property (an architecture of "
                        "embodied_snap/policy/architectures.py)")
    return None

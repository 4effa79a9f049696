"""The commands about a run's size and cost: `budget` (switch raw_data/ and results/ to another
budget's run) and `resources` (the SLURM profile's set-resources from a paper run's benchmarks)."""

from __future__ import annotations

import sys
from pathlib import Path

from .common import UsageError, config_args, existing_dir, existing_file, load_config


def add_resources(sub) -> None:
    rs = sub.add_parser("resources", help="write the SLURM profile's set-resources from a paper run's benchmarks")
    rs.add_argument("--benchmarks", default="benchmarks", help="benchmarks/ of a paper-budget run")
    rs.add_argument("--profile", default="profiles/slurm/config.yaml")
    rs.add_argument("--root", default=".", help="the workflow (its rules' benchmarks and threads)")
    rs.add_argument("--check", action="store_true", help="only compare; exit 1 when the profile differs")
    rs.set_defaults(fn=cmd_resources)


def add_budget(sub) -> None:
    bu = sub.add_parser("budget",
                        help="switch raw_data/ and results/ to another budget's run (the current one is kept)")
    bu.add_argument("name", nargs="?", help="paper, quick or smoke (default: config.yaml's budget)")
    bu.add_argument("--show", action="store_true", help="print the budget raw_data/ and results/ hold, and stop")
    config_args(bu)
    bu.set_defaults(fn=cmd_budget)


def cmd_resources(a) -> int:
    from ..lineage.dag import rule_table
    from ..lineage.records import instance
    from ..resources import ResourceError, render, set_resources, updated_profile

    existing_dir(a.root, "--root")
    existing_dir(a.benchmarks, "--benchmarks")
    existing_file(a.profile, "--profile")
    try:
        table = rule_table(a.root)
        per_shard = {r for r in table if instance(r, {})[0] != r}  # names that follow the budget's shards
        res, missing = set_resources(a.benchmarks, table, per_shard)
    except ResourceError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    profile = Path(a.profile)
    old = profile.read_text()
    new = updated_profile(old, render(res, missing))
    if missing:
        print(f"warning: not measured in {a.benchmarks} (default-resources): {', '.join(missing)}", file=sys.stderr)
    if a.check:
        if new != old:
            print(f"{profile}: set-resources differ from {a.benchmarks} (run esnap resources)", file=sys.stderr)
            return 1
        print(f"{profile}: set-resources match {a.benchmarks}")
        return 0
    profile.write_text(new)
    print(f"{profile}: set-resources of {len(res)} rules from {a.benchmarks}")
    return 0


def cmd_budget(a) -> int:
    """Switch raw_data/ and results/ to another budget's run, keeping this one's (docs/design.md)."""
    from .. import budget

    cfg = load_config(a)
    if a.show and a.name is not None:
        raise UsageError(f"{a.name!r} and --show: give one")
    if a.show:
        print(budget.shown(cfg))
        return 0
    try:
        print(budget.switch(cfg, cfg["budget"] if a.name is None else a.name))
    except budget.BudgetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0

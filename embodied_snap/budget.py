"""Budgets on one checkout: `raw_data/` and `results/` hold one budget's run at a time.

The active budget's trees stay where every rule, test and command expects them (`raw_data/`,
`results/`, `logs/`, `benchmarks/` and Snakemake's own records of them); the others wait, parked
whole, under `.budgets/<budget>/`. `.budgets/active.json` names the budget the trees hold.
`esnap budget NAME` parks the active trees and brings NAME's back (or leaves the place empty,
for NAME's first run), so a switch deletes nothing and never mixes two budgets' files: each
budget keeps its recordings, its sealed-set record and its results. A command that asks for a
budget the trees do not hold stops with one line naming both budgets and the command that fits.

An empty place fits every budget; the first run that asks claims it. Trees with no record
(made before budgets were recorded) are the twin budget whose plan their index.csv lists.
"""

from __future__ import annotations

import json
import os
import shlex
from pathlib import Path

from .files import write_text

HOME = ".budgets"
ACTIVE = f"{HOME}/active.json"
# What a run writes besides the raw tree: each travels with its budget. Snakemake's metadata
# must travel too, or a switch back would see every output as made with other params.
TREES = ("results", "logs", "benchmarks", ".snakemake/metadata", ".snakemake/incomplete", ".snakemake/esnap")


class BudgetError(ValueError):
    """One line: which budget the trees hold, which was asked for, and what to run."""


def trees(config: dict) -> list[str]:
    """The paths that belong to one budget's run: the raw tree too when the simulated rig wrote it
    (a real rig's recordings are the lab's, the same for every budget)."""
    raw = config["raw_data"]
    own_raw = raw["source"] == "twin" and not Path(raw["dir"]).is_absolute() and ".." not in Path(raw["dir"]).parts
    return ([raw["dir"]] if own_raw else []) + list(TREES)


def _held(root: Path, config: dict) -> list[str]:
    return [t for t in trees(config) if (root / t).exists() and any((root / t).iterdir())]


def _index_budget(raw: Path, config: dict) -> str | None:
    """The budget whose simulated-rig plan is exactly the groups of raw/index.csv."""
    import pandas as pd

    from .plan import twin_plan
    from .rawformat import RecordingError, raw_file

    try:
        index = raw_file(raw, "index.csv")  # a link out of the raw tree is the gate's to refuse, unread
        if not index.is_file():
            return None
        ids = set(pd.read_csv(index, usecols=["group_id"]).group_id)
    except (RecordingError, ValueError, UnicodeDecodeError, OSError):
        return None  # no budget's: what is wrong with it, the gate says next
    for name, b in config["budgets"].items():
        if set(twin_plan(b["groups"], config["sessions"]).group_id) == ids:
            return name
    return None


def active(config: dict, root=".") -> str | None:
    """The budget the trees hold; None when they are empty (or unknown)."""
    root = Path(root)
    if not _held(root, config):
        return None
    rec = root / ACTIVE
    if rec.exists():
        return json.loads(rec.read_text())["budget"]
    if config["raw_data"]["source"] != "twin":  # a lab's recordings are no budget's
        return None
    return _index_budget(root / config["raw_data"]["dir"], config)


def shown(config: dict, root=".") -> str:
    """The budget in place, as `esnap budget --show` says it: recorded, else read off the trees,
    else config's (an empty place is the budget a bare command asks for)."""
    rec = Path(root) / ACTIVE
    if rec.exists():
        return json.loads(rec.read_text())["budget"]
    return active(config, root) or config["budget"]


def _record(root: Path, name: str) -> None:
    write_text(root / ACTIVE, json.dumps({"budget": name}) + "\n")


def with_budget(argv: list[str], name: str) -> str:
    """The command line argv, asking for budget name (`--config budget=NAME`, as Snakemake takes it)."""
    out, i = [Path(argv[0]).name], 1
    while i < len(argv):
        if argv[i] == "--config":
            out.append(argv[i])
            i += 1
            while i < len(argv) and not argv[i].startswith("-") and "=" in argv[i]:
                if not argv[i].startswith("budget="):
                    out.append(argv[i])
                i += 1
            out.append(f"budget={name}")
            continue
        out.append(argv[i])
        i += 1
    if "--config" not in out:
        out += ["--config", f"budget={name}"]
    return shlex.join(out)


def claim(config: dict, root=".", argv: list[str] | None = None) -> str:
    """Before a run of config's budget: the trees hold it (or are empty, and now do), else one line
    naming both budgets, the switch, and argv (the command that asked) asking for the trees' budget."""
    root, asked = Path(root), config["budget"]
    held = fits(config, root, argv)
    if held is None or not (root / ACTIVE).exists():
        _record(root, asked)
    return asked


def fits(config: dict, root=".", argv: list[str] | None = None) -> str | None:
    """The budget the trees hold (None: empty) when config asks for it; else the one line."""
    root, asked = Path(root), config["budget"]
    held = active(config, root)
    if held is None or held == asked:
        return held
    raise BudgetError(
        f"raw_data/ and results/ hold the {held} budget's run and this asks for {asked}: "
        f"`esnap budget {asked}` switches (keeping {held}'s in {HOME}/{held}/), "
        f"or ask for {held}'s: `{with_budget(argv or ['snakemake'], held)}`"
    )


def switch(config: dict, name: str, root=".") -> str:
    """Park the active budget's trees under .budgets/<it>/ and bring name's back. A one-line
    summary; BudgetError when a run holds the directory or a parked tree would be overwritten."""
    root = Path(root)
    if name not in config["budgets"]:
        raise BudgetError(f"budget {name!r}: not one of {', '.join(config['budgets'])} (config budgets:)")
    locks = root / ".snakemake" / "locks"
    if locks.exists() and any(locks.iterdir()):
        raise BudgetError("a Snakemake run holds this directory (.snakemake/locks): "
                          "wait for it to end, or `snakemake --unlock` if none runs")
    held = active(config, root)
    if held == name:
        return f"raw_data/ and results/ already hold the {name} budget's run"
    present = _held(root, config)
    if present and held is None:
        raise BudgetError(f"{', '.join(present)}: a run of no known budget: move it aside, "
                          f"or claim it with `snakemake --config budget=NAME -n`")
    parked, back = root / HOME / str(held), root / HOME / name
    clash = [t for t in present if (parked / t).exists()]
    if clash:
        raise BudgetError(f"{parked / clash[0]} exists: {held}'s parked trees would be overwritten")
    for t in present:
        (parked / t).parent.mkdir(parents=True, exist_ok=True)
        os.replace(root / t, parked / t)
    restored = []
    for t in trees(config):
        if (back / t).exists():
            if (root / t).exists():  # left empty by the park above
                os.rmdir(root / t)
            (root / t).parent.mkdir(parents=True, exist_ok=True)
            os.replace(back / t, root / t)
            restored.append(t)
    for d in sorted(back.glob("**/"), reverse=True) if back.exists() else []:
        if not any(d.iterdir()):
            d.rmdir()  # the empty folders the trees came back from
    _record(root, name)
    kept = f"; the {held} budget's run is kept in {parked.relative_to(root)}/" if present else ""
    now = "its run is back" if restored else "empty: the next run records it"
    return f"raw_data/ and results/ now hold the {name} budget ({now}){kept}"


def check_tree(config: dict, raw, argv: list[str] | None = None) -> None:
    """Before `esnap validate` or `esnap seal` reads raw for config's budget: a tree whose index.csv
    lists exactly another budget's simulated-rig groups is that budget's (a lab's tree is no
    budget's). Else one line with the command that fits."""
    held = _index_budget(Path(raw), config)
    if held not in (None, config["budget"]):
        raise BudgetError(f"{raw} holds the {held} budget's recordings and this asks for {config['budget']}: "
                          f"`{with_budget(argv or ['esnap'], held)}`")

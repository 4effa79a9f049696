"""The paper's numbers, read from reference/paper_values.yaml: the reference column, never a result."""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import yaml

from .sources import named, trace

REFERENCE = Path(__file__).resolve().parent.parent / "reference" / "paper_values.yaml"


@cache
def paper_values(path: str | Path = REFERENCE) -> dict:
    with open(path) as f:
        return yaml.safe_load(f)


def _within(value, lo, hi) -> bool:
    vals = value if isinstance(value, (list, tuple)) else [value]
    return all(v is not None and not math.isnan(v) and lo <= v <= hi for v in vals)


def twin_comparison(phenomena: dict, path: str | Path = REFERENCE) -> list[dict]:
    """One row per twin phenomenon: paper value, ours, the accepted range, and whether we are in it."""
    rows = []
    for key, ref in paper_values(path)["twin_phenomena"].items():
        ours = phenomena.get(key)
        lo, hi = (float(x) for x in ref["twin_range"])
        rows.append(
            dict(
                key=key,
                section=ref["section"],
                quantity=ref["quantity"],
                paper=ref["paper"],
                ours=ours,
                twin_range=[lo, hi],
                unit=ref["unit"],
                ok=ours is not None and _within(ours, lo, hi),
            )
        )
    return rows


def fmt(v) -> str:
    """A number with 4 significant digits, a range as [lo, hi], NaN as empty."""
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def paper_column(section: str, path: str | Path = REFERENCE) -> dict:
    """claim id -> the paper's value, of one section: for tables that set ours beside the paper's."""
    return {cid: r["paper"] for cid, r in paper_values(path)[section].items()}


def claim_rows(section: str, ours, artifacts: dict, path: str | Path = REFERENCE) -> list[dict]:
    """Rows of a stage's claims.csv: every claim of `section` in the reference file, the paper's value
    beside ours, and where ours was read (`source`, artifact:key). `ours(views, out)` assigns each
    claim to `out` from the artifacts' views (embodied_snap.sources.trace); `artifacts`: name ->
    (path, JSON value), or a list of them, or a bare value (named by its name, in tests)."""
    values, sources = trace(ours, named(artifacts))
    return [
        dict(claim_id=cid, section=r["section"], quantity=r["quantity"], paper=fmt(r["paper"]),
             ours=fmt(values[cid]), unit=r["unit"], source=sources[cid])
        for cid, r in paper_values(path)[section].items()
    ]


def by_construction(stage: str, claim_id: str, path: str | Path = REFERENCE) -> str | None:
    """Why the simulated rig agrees with this claim by construction: its `by_construction:` (an input
    of the rig taken from a paper result, docs/twin.md), else None."""
    return ((paper_values(path).get(stage) or {}).get(claim_id) or {}).get("by_construction")


def tolerance(stage: str, claim_id: str, path: str | Path = REFERENCE) -> float:
    """The relative tolerance the claims ledger allows a point value of `stage`: the claim's own
    `tolerance`, else `agreement.relative_tolerance`."""
    ref = paper_values(path)
    own = (ref.get(stage) or {}).get(claim_id, {}).get("tolerance")
    return float(own if own is not None else ref["agreement"]["relative_tolerance"])

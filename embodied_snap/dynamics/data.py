"""What the dynamics jobs read besides windows: resampled shards and the groups' meta.json."""

from __future__ import annotations

import json

import pandas as pd

from ..io import read_parquet


def frames(shards, groups=None) -> pd.DataFrame:
    """50 Hz frames of the given shards, optionally only some groups, sorted by group and time."""
    f = pd.concat([read_parquet(p) for p in shards], ignore_index=True)
    if groups is not None:
        f = f[f.group_id.isin(set(groups))]
    return f.sort_values(["group_id", "t"], kind="stable").reset_index(drop=True)


def metas(paths) -> dict[str, dict]:
    out = {}
    for p in paths:
        m = json.load(open(p))
        out[m["group_id"]] = m
    return out

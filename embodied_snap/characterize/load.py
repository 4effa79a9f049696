"""Reading recordings for the fits: one group's mocap, servo log and meta."""

from __future__ import annotations

import pandas as pd

from .. import rawformat as RF
from ..io import read_parquet
from ..rawschema import as_float64


def group(raw_dir, gid: str) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    p = RF.group_paths(raw_dir, gid)
    # float32 columns read as float64, as the gate read them
    return as_float64(read_parquet(p["mocap"])), as_float64(read_parquet(p["servo"])), RF.read_meta(p["meta"])


def release_start(meta: dict) -> float:
    """When the release begins: the distal slackening of a primitive, else the direct release."""
    lab = meta.get("labels", {})
    for k in ("t_slack", "t_release", "t_s2"):
        if k in lab:
            return float(lab[k])
    return 0.0

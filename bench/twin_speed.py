"""Simulated rig acquisition speed: simulated seconds per wall second and groups per second.

    python bench/twin_speed.py [--per-category 2] [--dt 0.001]

Acquires a few groups of every category of the paper budget (one process), then extrapolates the
paper budget's wall time on 2 cores (2 parallel jobs).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import pandas as pd
import yaml

from embodied_snap import rawformat as RF
from embodied_snap.plan import twin_plan
from embodied_snap.protocol import load
from embodied_snap.twin.acquire import acquire_groups, nominal_strike


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-category", type=int, default=2)
    ap.add_argument("--dt", type=float, default=0.001)
    ap.add_argument("--config", default=str(Path(__file__).resolve().parents[1] / "config.yaml"))
    a = ap.parse_args()
    cfg = yaml.safe_load(open(a.config))
    plan = twin_plan(cfg["budgets"]["paper"]["groups"], cfg["sessions"])
    pick = plan.groupby(["evidence_set", "category"], sort=False).head(a.per_category)
    proto = load(cfg)
    nominal_strike(a.dt, proto)  # once per process; not counted per group
    with tempfile.TemporaryDirectory() as d:
        t0, c0 = time.perf_counter(), time.process_time()
        hold = cfg["twin"]["held_base"]
        rows = acquire_groups(pick, d, seed=cfg["seed"], proto=proto, dt=a.dt, hold=hold, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0  # CPU: fair on a shared machine
        sim_s = 0.0
        per_cat = {}
        for r in rows:
            mc = pd.read_parquet(RF.group_paths(d, r["group_id"])["mocap"], columns=["t"])
            sim_s += float(mc.t.iloc[-1])
            per_cat.setdefault((r["evidence_set"], r["category"]), []).append(float(mc.t.iloc[-1]))
    n = len(rows)
    print(f"groups: {n}  wall: {wall:.2f} s  simulated: {sim_s:.1f} s")
    print(f"simulated seconds per wall second: {sim_s / wall:.1f}")
    print(f"simulated seconds per CPU second: {sim_s / cpu:.1f}")
    print(f"groups per second (1 process): {n / wall:.2f}")
    # paper budget: weight each category's mean simulated length by its count
    rate = sim_s / wall
    total = 0.0
    for (es, cat), ts in per_cat.items():
        total += sum(ts) / len(ts) * int((plan.evidence_set.eq(es) & plan.category.eq(cat)).sum())
    print(
        f"paper budget: {len(plan)} groups, ~{total:.0f} simulated s, "
        f"~{total / rate / 2 / 60:.1f} min on 2 cores (2 jobs)"
    )


if __name__ == "__main__":
    main()

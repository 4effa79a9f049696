"""The gate's throughput on a real raw tree (e.g. a paper-budget run's raw_data/), for
docs/benchmarks.md.

    python bench/validate_speed.py RAW_DIR [--groups 200] [--repeat 3] [--config config.yaml]

Times validate_group over `--groups` groups spread evenly over RAW_DIR/index.csv (every
evidence set), each against its
index row, with the config's limits (best of `--repeat` passes, one process, pyarrow on one
thread). Reads RAW_DIR only.
"""

from __future__ import annotations

import argparse
import time

import pyarrow as pa
import yaml

from embodied_snap.validate import Limits, read_index, validate_group


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("raw_dir")
    ap.add_argument("--groups", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--config", default="config.yaml", help="the limits (gate, resample keys)")
    a = ap.parse_args(argv)
    pa.set_cpu_count(1)  # one core: what one validate_shard job gets
    pa.set_io_thread_count(1)
    with open(a.config) as f:
        limits = Limits.from_config(yaml.safe_load(f))
    rows = read_index(a.raw_dir, limits.group_id_pattern).to_dict("records")
    rows = rows[:: max(1, len(rows) // a.groups)][: a.groups]
    validate_group(a.raw_dir, rows[0]["group_id"], rows[0], limits=limits)  # warm-up: imports, caches
    best = float("inf")
    for _ in range(a.repeat):
        t = time.perf_counter()
        for r in rows:
            validate_group(a.raw_dir, r["group_id"], r, limits=limits)
        best = min(best, time.perf_counter() - t)
    n = len(rows)
    print(f"{n} groups of {a.raw_dir}")
    print(f"validate: {n / best:.1f} groups/s, {1000 * best / n:.2f} ms/group (best of {a.repeat})")


if __name__ == "__main__":
    main()

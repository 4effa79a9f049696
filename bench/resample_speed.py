"""Per-group resampling throughput on fakerig groups (~6 s each), for docs/benchmarks.md.

    python bench/resample_speed.py [--groups 24] [--duration 6] [--repeat 3] [--validate]

Writes the groups to a temporary raw_data/, then times resample_group over all of them (best of
`--repeat` passes, one process, one core); `--validate` also times validate_group.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import yaml  # noqa: E402

from embodied_snap.protocol import load  # noqa: E402
from embodied_snap.resample import resample_group  # noqa: E402
from embodied_snap.validate import Limits, validate_group  # noqa: E402

from fakerig import write_fake_raw  # noqa: E402

CONFIG = yaml.safe_load((Path(__file__).resolve().parents[1] / "config.yaml").read_text())
SAMPLING = load(CONFIG).sampling  # config resample: the grid the benchmark times
HZ, MAX_GAP_S = SAMPLING.hz, SAMPLING.max_gap_s
LIMITS = Limits.from_config(CONFIG)


def best_time(fn, ids, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        for g in ids:
            fn(g)
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--groups", type=int, default=24)
    ap.add_argument("--duration", type=float, default=6.0, help="seconds of mocap per group")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--validate", action="store_true", help="also time validate_group")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        ids = [f"dyn_{i + 1:04d}" for i in range(a.groups)]
        write_fake_raw(d, ids, duration_s=a.duration)
        resample_group(d, ids[0], HZ, MAX_GAP_S)  # warm-up: imports, first parquet read
        rows = sum(len(resample_group(d, g, HZ, MAX_GAP_S)) for g in ids)
        runs = [("resample", lambda g: resample_group(d, g, HZ, MAX_GAP_S))]
        if a.validate:
            runs.append(("validate", lambda g: validate_group(d, g, limits=LIMITS)))
        print(f"{a.groups} fakerig groups of {a.duration:g} s ({rows // a.groups} rows at 50 Hz each)")
        for name, fn in runs:
            s = best_time(fn, ids, a.repeat)
            print(
                f"{name}: {a.groups / s:.1f} groups/s, {1000 * s / a.groups:.2f} ms/group (best of {a.repeat})"
            )


if __name__ == "__main__":
    main()

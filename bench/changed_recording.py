"""One changed recording, then the figures again: how long a user waits for the rebuild.

    python bench/changed_recording.py [--group att_0003] [--target results/figures] [--config budget=paper]

On a finished tree: moves one motion-capture sample of the group by 0.1 mm (the tip's x in its
middle row, written with the recording format's own writer, the file's mode kept), then times
`snakemake --cores 2 TARGET` and prints its wall time and the jobs it ran (from the run's log, in
seconds from the first job's start). Every call moves the sample again: each is a change.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from embodied_snap.io import write_parquet
from embodied_snap.rawformat import group_paths

sys.path.insert(0, str(Path(__file__).resolve().parent))
from timeline import jobs  # noqa: E402 -- bench/ beside this file

BIN = Path(sys.executable).parent


def change_one_sample(raw: str, group: str) -> Path:
    path = group_paths(raw, group)["mocap"]
    df = pd.read_parquet(path)
    df.loc[len(df) // 2, "tip_x"] += 1e-4  # 0.1 mm
    mode = path.stat().st_mode
    os.chmod(path, mode | 0o200)
    write_parquet(df, path)
    os.chmod(path, mode)
    return path


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--group", default="att_0003")
    ap.add_argument("--raw", default="raw_data")
    ap.add_argument("--target", default="results/figures")
    ap.add_argument("--config", nargs="*", default=[], help="passed to snakemake --config")
    a = ap.parse_args(argv)
    print(f"changed: {change_one_sample(a.raw, a.group)}")
    logs = set(Path(".snakemake/log").glob("*.snakemake.log"))
    cmd = [str(BIN / "snakemake"), "--cores", "2", a.target, *(["--config", *a.config] if a.config else [])]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode:
        sys.exit(f"error: {' '.join(cmd)} failed (rc {r.returncode}):\n{r.stderr[-2000:]}")
    (log,) = set(Path(".snakemake/log").glob("*.snakemake.log")) - logs
    js = jobs(log)
    print(f"{' '.join(cmd[1:])}: {wall:.1f} s wall, {len(js)} jobs")
    for j in js:
        print(f"  {j['start']:5.0f} {j['end']:5.0f}  {j['rule']}{'(' + j['wildcards'] + ')' if j['wildcards'] else ''}")


if __name__ == "__main__":
    main()

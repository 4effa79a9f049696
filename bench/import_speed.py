"""`esnap import`'s throughput, for docs/benchmarks.md: a native raw tree (e.g. a paper-budget run's
raw_data/) written out as a lab's sessions, then imported, on one core.

    python bench/import_speed.py RAW_DIR WORK_DIR [--fmt motive|c3d] [--rate 120] [--sync event|none]
    python bench/import_speed.py RAW_DIR - --floor

Writes WORK_DIR/export (tests/labexport.py: Motive CSV in mm or C3D markers, servo logs 0.137 s
behind, operator sheets) and imports every session into WORK_DIR/raw (in this process, pyarrow on
one thread, no progress bar). Prints the export and import times, takes/s, and with `--sync none`
how the clock estimates fell against the known offset. Reads RAW_DIR only.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

OFFSET_S = 0.137  # the servo clock behind the capture's (labexport.servo_clock)


def main(argv=None):
    import yaml

    from embodied_snap import runconfig
    from embodied_snap.capture.errors import CaptureError
    from embodied_snap.capture.importer import ImportRefused, import_session
    from embodied_snap.capture.lab import load_lab

    from labexport import export_tree

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("raw_dir")
    ap.add_argument("work_dir")
    ap.add_argument("--fmt", choices=["motive", "c3d"], default="motive")
    ap.add_argument("--rate", type=float, default=120)
    ap.add_argument("--sync", choices=["event", "none"], default="event")
    ap.add_argument("--config", action="append", default=[], help="K=V, as esnap's --config")
    ap.add_argument("--floor", action="store_true",
                    help="fit the clock on RAW_DIR's own groups, one clock and no offset: the method's floor")
    ap.add_argument("--reuse", action="store_true", help="import WORK_DIR/export as it is (written by an earlier run)")
    a = ap.parse_args(argv)
    pa.set_cpu_count(1)
    pa.set_io_thread_count(1)
    if a.floor:
        return floor(Path(a.raw_dir), runconfig.load(None, a.config))
    work = Path(a.work_dir)
    shutil.rmtree(work / "raw", ignore_errors=True)
    t = time.perf_counter()
    if a.reuse:
        sessions = sorted((work / "export").glob("*.yaml"))
        sessions = [s for s in sessions if s.name != "lab.yaml"]
    else:
        shutil.rmtree(work, ignore_errors=True)
        sessions = export_tree(a.raw_dir, work / "export", fmt=a.fmt, rate_hz=a.rate, offset_s=OFFSET_S)
    t_export = time.perf_counter() - t
    lab_path = work / "export" / "lab.yaml"
    doc = yaml.safe_load(lab_path.read_text())
    if a.sync == "event":  # the export's clock starts at the native first frame, t = 0.001 s
        doc["clock"] = dict(sync=dict(event_time_s=OFFSET_S - 0.001), max_drift_ppm=100)
    else:
        doc["clock"] = dict(sync="none", max_drift_ppm=100)
    lab_path.write_text(yaml.safe_dump(doc, sort_keys=False))
    lab = load_lab(lab_path)
    cfg = runconfig.load(None, a.config)
    if a.sync == "none":  # every take's clock fit on its own (no gate, nothing written), refused ones counted
        from embodied_snap.capture.importer import build_group, load_session

        err, bad, t = [], [], time.perf_counter()
        for s in sessions:
            for spec in load_session(s):
                try:
                    err.append(build_group(spec, lab, cfg)[0]["clock"]["offset_s"] - (OFFSET_S - 0.001))
                except CaptureError as e:
                    bad.append(f"{spec.meta['group_id']}: {e.line}")
        dt = time.perf_counter() - t
        err, frame = np.array(err) * 1e3, 1e3 / a.rate
        print(f"clock fit on {len(err) + len(bad)} takes in {dt:.1f} s: {len(bad)} refused; offset error (ms) median "
              f"{np.median(err):+.1f}, |err| p90 {np.percentile(abs(err), 90):.1f}, max {abs(err).max():.1f}; "
              f"within one frame ({frame:.1f} ms): {(abs(err) <= frame).sum()} of {len(err)}")
        kinds = {}
        for line in bad:
            kinds[line.split(": ", 1)[1].split(":")[0]] = kinds.get(line.split(": ", 1)[1].split(":")[0], 0) + 1
        print("  refused:", kinds)
        return
    n, refused, t = 0, [], time.perf_counter()
    for s in sessions:
        try:
            n += len(import_session(s, lab, work / "raw", cfg))
        except (CaptureError, ImportRefused) as e:
            refused.append(str(e))
    t_import = time.perf_counter() - t
    print(f"{len(sessions)} sessions: export {t_export:.1f} s; import {n} takes in {t_import:.1f} s "
          f"({n / t_import:.2f} takes/s, one core); {len(refused)} session(s) refused")
    for line in refused:
        print(f"  refused: {line}")

def floor(raw: Path, cfg: dict) -> None:
    """The clock fit where the truth is 0: each native group's mocap and servo log share one clock,
    so every millisecond of the estimate is the method's (the arm's lag behind its servos)."""
    import pandas as pd

    from embodied_snap.capture.clock import ClockFitOptions, estimate_offset
    from embodied_snap.capture.errors import CaptureError
    from embodied_snap.capture.importer import MIN_OVERLAP_S, MIN_PEAK_CORRELATION, clock_signals
    from embodied_snap.capture.lab import MAX_OFFSET_S

    gap, err, bad = cfg["resample"]["max_gap_s"], [], 0
    for g in sorted((raw / "groups").iterdir()):
        m, s = pd.read_parquet(g / "mocap.parquet"), pd.read_parquet(g / "servo.parquet")
        _, motion, command = clock_signals(m, s, gap)
        try:
            options = ClockFitOptions(max_shift_s=MAX_OFFSET_S, max_gap_s=gap, min_overlap_s=MIN_OVERLAP_S,
                                      min_peak_correlation=MIN_PEAK_CORRELATION)
            err.append(estimate_offset(m.t.to_numpy(), motion, s.t.to_numpy(), command, options).offset_s)
        except CaptureError:
            bad += 1
    e = np.array(err) * 1e3
    print(f"clock fit on {len(e) + bad} native groups (one clock, true offset 0): {bad} refused; estimate (ms) "
          f"median {np.median(e):+.1f}, |err| p90 {np.percentile(abs(e), 90):.1f}, max {abs(e).max():.1f}")


if __name__ == "__main__":
    main()

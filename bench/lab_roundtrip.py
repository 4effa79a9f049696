"""The lab's acquisition end to end on the simulated rig, against the simulated rig's own run.

    python bench/lab_roundtrip.py WORK [--budget smoke] [--native DIR]

In WORK (a copy of the workflow): `esnap lab plan`, then `esnap lab acquire` of every group over the
virtual Protocol 2.0 bus (tests/simlab.py: the arm driven live, the held-base push at the cue, each
take exported as a 120 Hz Motive CSV named by its group id; a group that aborts, e.g. a reply lost
on a busy machine, is recorded again on the resume, as a lab would), `esnap import` of every
session with the clock estimated from the data, `esnap validate`, the workflow with
`raw_data.source: rig`; then the deployment trials over the same bus from the manifest that run
exported (esnap deploy's client; `esnap deploy-index`) and the workflow again, so every figure is
built. The native run (`snakemake --config budget=...` in --native, made here when not given) is the
simulated rig's acquisition of the same plan. Prints the times, the clock estimates and
bench/compare_ledgers.py's comparison of the two ledgers.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))
COPY = ["Snakefile", "config.yaml", "rules", "workflow_scripts", "schemas", "envs", "profiles", "reference",
        "report", "embodied_snap", "docs"]
BIN = Path(sys.executable).parent


def run(cmd, cwd, log=None):
    env = {**os.environ, "PYTHONPATH": str(cwd), "PATH": f"{BIN}:{os.environ['PATH']}"}
    t = time.time()
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if log:
        Path(log).write_text(r.stdout + r.stderr)
    if r.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return time.time() - t


def workflow_copy(dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    for name in COPY:
        src = REPO / name
        if not (dest / name).exists():
            (shutil.copytree if src.is_dir() else shutil.copy2)(
                src, dest / name, **({"ignore": shutil.ignore_patterns("__pycache__")} if src.is_dir() else {}))
    return dest


def clock_estimates(sessions: Path, lab_path: Path, work: Path, rate_hz: float) -> str:
    """Every take's clock estimated from the data (no sync; nothing written): the offsets found
    against the true one (0 s to within 1 ms here) and the takes refused."""
    import numpy as np

    from embodied_snap import runconfig
    from embodied_snap.capture.errors import CaptureError
    from embodied_snap.capture.importer import build_group, load_session
    from embodied_snap.capture.lab import load_lab

    lab, cfg = load_lab(lab_path), runconfig.load(root=work)
    got, refused = [], []
    for s in sorted(sessions.glob("s*.yaml")):
        for spec in load_session(s):
            try:
                got.append(build_group(spec, lab, cfg)[0]["clock"]["offset_s"])
            except CaptureError as e:
                refused.append(f"{spec.meta['group_id']}: {e.line}")
    e = np.abs(np.asarray(got)) * 1e3
    for line in refused:
        print(f"  clock refused: {line}")
    return (f"clock from the data, no sync, {len(got) + len(refused)} takes: {len(refused)} refused; |offset error| "
            f"median {np.median(e):.1f} ms, p90 {np.percentile(e, 90):.1f} ms, max {e.max():.1f} ms, within one "
            f"{rate_hz:g} Hz frame ({1e3 / rate_hz:.1f} ms) {int((e <= 1e3 / rate_hz).sum())} of {len(e)}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work")
    ap.add_argument("--budget", default="smoke")
    ap.add_argument("--capture-hz", type=float, default=120, help="the rate the takes are exported at")
    ap.add_argument("--native", help="a finished native run of the budget (its results/tables/claims.csv)")
    a = ap.parse_args()
    import yaml
    from simlab import SimLab

    from embodied_snap.lab.acquire import LabError

    from labexport import lab_doc

    work = workflow_copy(Path(a.work).resolve())
    budget = ["--config", f"budget={a.budget}"]
    times = {}
    plan = work / "plan.yaml"
    if not plan.exists():
        times["plan"] = run([BIN / "esnap", "lab", "plan", "--budget", a.budget, "--out", plan], work)
    sessions = work / "sessions"
    lab = SimLab(plan, sessions, capture_hz=a.capture_hz)
    t, aborts = time.time(), []
    while True:  # resume after an abort, as the operator would
        try:
            got = lab.acquire()
        except LabError as e:
            aborts.append(str(e))
            print(f"abort, resuming: {e}", flush=True)
            lab = SimLab(plan, sessions, capture_hz=a.capture_hz)
            continue
        if not got["left"]:
            break
    times["acquire"] = time.time() - t
    # The virtual rig's capture starts with the program (its first frame is the program's first
    # physics step, 1 ms in; the servo log's first sync-read under 1 ms after its first goal): a lab
    # whose servo PC triggers the take, `sync: {event_time_s: 0}`. The estimate from the data, with
    # no sync, is measured beside it on every take.
    labfile, nosync = work / "lab.yaml", work / "lab_nosync.yaml"
    labfile.write_text(yaml.safe_dump(lab_doc("rigid_body", dict(sync=dict(event_time_s=0.0), max_drift_ppm=100))))
    nosync.write_text(yaml.safe_dump(lab_doc("rigid_body", dict(sync="none", max_drift_ppm=100))))
    clock = clock_estimates(sessions, nosync, work, a.capture_hz)
    raw = "lab/recordings"
    t = time.time()
    for s in sorted(sessions.glob("s*.yaml")):
        run([BIN / "esnap", "import", s, "--lab", labfile, "--raw", raw, "--quiet", *budget], work)
    times["import"] = time.time() - t
    times["validate"] = run([BIN / "esnap", "validate", raw, "--source", "rig", *budget], work)
    rig = [*budget, f"raw_data={{source: rig, dir: {raw}}}"]
    times["workflow"] = run(["snakemake", "--cores", "2", "results/figures", *rig], work, work / "workflow.log")
    # the deployment trials from the manifest that run exported, over the same virtual bus
    cfg = yaml.safe_load((work / "config.yaml").read_text())
    dep = cfg["budgets"][a.budget]["deployment"]
    from embodied_snap.twin.deployment import DeploymentSetup, run_trial

    setup = DeploymentSetup(raw=work / raw / "deployment", seed=cfg["seed"], n_sessions=cfg["sessions"],
                            dt=cfg["twin"]["dt"], speed_mps=cfg["characterize"]["attach_speed_mps"])
    t, k = time.time(), 0
    for _ in range(dep["trials_per_placement"]):
        for placement in range(1, dep["placements"] + 1):
            k += 1
            row = run_trial(work / "results/deployment/manifest.json", placement, k, setup)
            if "cause" in row:
                print(f"deployment trial {k} aborted: {row['cause']}", flush=True)
    times["deploy"] = time.time() - t
    run([BIN / "esnap", "deploy-index", "--raw", f"{raw}/deployment", "--planned", str(k), *rig], work)
    times["workflow_all"] = run(["snakemake", "--cores", "2", "all", *rig], work, work / "workflow_all.log")
    native = Path(a.native).resolve() if a.native else None
    if native is None:
        native = workflow_copy(work.parent / f"{work.name}_native")
        times["native"] = run(["snakemake", "--cores", "2", "all", *budget], native, native / "workflow.log")
    print(f"groups {len(list((work / raw / 'groups').iterdir()))}, aborts resumed {len(aborts)}; {clock}")
    print("times (s): " + ", ".join(f"{k} {v:.0f}" for k, v in times.items()))
    for x in aborts:
        print(f"  abort: {x}")
    subprocess.run([sys.executable, str(REPO / "bench/compare_ledgers.py"), str(native / "results/tables/claims.csv"),
                    str(work / "results/tables/claims.csv")])
    return 0


if __name__ == "__main__":
    sys.exit(main())

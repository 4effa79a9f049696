"""The paper budget's two GPU stages on one device: the 18 searches in lockstep and a GRU seed's
training, timed, with the GPU's utilisation; the lockstep's determinism on the device, the
one-job-per-run schedule beside it, and the CPU's runs beside the device's.

    python bench/device_stages.py RESULTS_DIR [--device cuda] [--generations 120] [--short 10]
                                  [--cpu-threads N] [--out device.json] [--skip train,cpu]

RESULTS_DIR is a finished run's `results/` (any budget: the models, hold bank, P_snap, workspace
and windows; the cost of a rollout or a training step does not depend on the weights). The
targets are drawn as `policy_targets` draws them, at the paper budget's sizes and seeds. Steps,
each printed and written to --out as it ends (a step that fails says why and the next runs):
  repeat     the paper's runs (config budgets.paper.policy.seeds) in lockstep for --short
             generations, twice: identical runs on the device?
  alone      one run alone for --short generations (the one-job-per-run schedule, per run)
  lockstep   the paper's runs in lockstep for --generations
  train      one GRU seed at the paper's epochs and windows per epoch (windows repeated to reach them)
  cpu        the lockstep for --short generations on the CPU (--cpu-threads): each architecture's
             mean selection reward beside the device's, with the seeds' spread
Utilisation: NVML's GPU busy %, sampled every 0.2 s during each step (mean and max).
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from pathlib import Path

import numpy as np
import torch
import yaml

from embodied_snap.dynamics import train as T
from embodied_snap.policy import search, simulate, targets
from embodied_snap.policy.evaluations import training_targets
from embodied_snap.windows import load_windows

ROOT = Path(__file__).resolve().parent.parent


class Busy:
    """NVML's utilisation of GPU 0, sampled in a thread while the block runs."""

    def __enter__(self):
        self.samples, self.stop = [], threading.Event()
        try:
            import pynvml

            pynvml.nvmlInit()
            h = pynvml.nvmlDeviceGetHandleByIndex(0)
            read = lambda: pynvml.nvmlDeviceGetUtilizationRates(h).gpu  # noqa: E731
        except Exception:  # noqa: BLE001 -- no NVML (CPU): no samples
            return self

        def loop():
            while not self.stop.wait(0.2):
                self.samples.append(read())

        self.t = threading.Thread(target=loop, daemon=True)
        self.t.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        return False

    def summary(self) -> dict:
        s = self.samples
        return dict(util_mean=float(np.mean(s)) if s else None, util_max=max(s) if s else None, samples=len(s))


def paper_targets(ws: dict, cfg: dict) -> tuple:
    b, p = cfg["budgets"]["paper"]["policy"], cfg["policy"]
    tr = targets.sample(ws, training_targets(b["generations"], b["targets_per_candidate"]),
                        p["target_seeds"]["training"], p["arc_deg"], p["target_jitter_m"])
    gen = tr.index.to_numpy() // b["targets_per_candidate"]
    sel = targets.sample(ws, b["selection_targets"], p["target_seeds"]["selection"], p["arc_deg"],
                         p["target_jitter_m"])
    return search.Targets(tr, ws), gen, search.Targets(sel, ws)


def tiled(W: dict, n: int) -> dict:
    """Windows repeated until there are n anchors (a step's cost is the same on any window)."""
    k = len(W["anchors"])
    return {key: np.resize(v, n) if getattr(v, "shape", ()) == (k,) else v for key, v in W.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--generations", type=int, default=120)
    ap.add_argument("--short", type=int, default=10)
    ap.add_argument("--cpu-threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--out", type=Path, default=Path("device.json"))
    ap.add_argument("--skip", default="")
    a = ap.parse_args()
    skip = set(a.skip.split(",")) - {""}
    cfg = yaml.safe_load((ROOT / "config.yaml").read_text())
    b, p, R = cfg["budgets"]["paper"]["policy"], cfg["policy"], a.results
    runs = [(arch, s, None) for arch, n in b["seeds"].items() for s in range(n)]
    out = dict(device=a.device, name=torch.cuda.get_device_name(0) if torch.cuda.is_available() else "cpu",
               torch=torch.__version__, runs=len(runs), popsize=b["popsize"],
               targets_per_candidate=b["targets_per_candidate"], selection_targets=b["selection_targets"])

    def sim_on(device):
        return simulate.from_files(sorted(map(str, R.glob("dynamics/models/seed*.pt"))), R / "dynamics/hold_bank.npz",
                                   R / "characterize/snap.json", R / "policy/workspace.json",
                                   simulate.SimSettings.from_config(cfg), device=device)

    def sync():
        if torch.cuda.is_available():
            torch.cuda.synchronize()

    def step(name, fn):
        with Busy() as busy:
            t0 = time.perf_counter()
            try:
                res = fn()
            except Exception as e:  # noqa: BLE001 -- say what failed, go on to the next step
                res = dict(error=f"{type(e).__name__}: {e}")
            sync()
            dt = time.perf_counter() - t0
        out[name] = dict(wall_s=round(dt, 2), **busy.summary(), **(res or {}))
        print(name, json.dumps(out[name]), flush=True)
        a.out.write_text(json.dumps(out, indent=1))

    sim, ws = sim_on(a.device)
    train, gen, sel = paper_targets(ws, cfg)
    tgt = search.SearchTargets(train=train, gen_of=gen, select=sel, norm=search.feature_stats(train))

    def spec(G):
        return search.SearchSpec(ranges=p["ranges"], generations=G, popsize=b["popsize"], start=p["start"])

    def lockstep(s, G, rs=runs):
        return search.lockstep(s, rs, tgt, spec(G), progress=False)

    def strip(done):
        return [{k: v for k, v in r.items() if k != "state"} for r in done]

    def per_arch(done):
        by = {}
        for r in done:
            by.setdefault(r["arch"], []).append(r["selection_reward"])
        return {k: dict(mean=float(np.mean(v)), sd=float(np.std(v, ddof=1)) if len(v) > 1 else 0.0, n=len(v))
                for k, v in by.items()}

    short = {}

    def repeat():
        short["a"], short["b"] = (strip(lockstep(sim, a.short)) for _ in range(2))
        return dict(generations=a.short, identical=short["a"] == short["b"])

    def alone():
        search.cmaes(sim, "shared", 0, tgt, spec(a.short), progress=False)
        return dict(generations=a.short, runs=1)

    def full():
        return dict(generations=a.generations, per_arch=per_arch(lockstep(sim, a.generations)))

    step("repeat", repeat)
    step("alone", alone)
    out["alone"]["s_per_run_generation"] = round(out["alone"]["wall_s"] / a.short, 3)
    out["repeat"]["s_per_run_generation"] = round(out["repeat"]["wall_s"] / 2 / a.short / len(runs), 4)
    step("lockstep", full)
    out["lockstep"]["s_per_generation"] = round(out["lockstep"]["wall_s"] / a.generations, 3)
    if "train" not in skip:
        d, db = cfg["dynamics"], cfg["budgets"]["paper"]["dynamics"]
        Wtr = tiled(load_windows(R / "splits/windows_train.npz"), db["windows_per_epoch"])
        Wva = tiled(load_windows(R / "splits/windows_validation.npz"), d["val_windows"])

        def fit():
            settings = T.TrainSettings(epochs=db["epochs"], windows_per_epoch=db["windows_per_epoch"],
                                       val_windows=d["val_windows"], batch_size=d["batch_size"], lr=d["lr"],
                                       patience=db["epochs"], device=a.device)
            T.train(Wtr, Wva, 0, settings, log=lambda r: None)
            return dict(epochs=db["epochs"], windows_per_epoch=db["windows_per_epoch"])

        step("train", fit)
    if "cpu" not in skip:
        torch.set_num_threads(a.cpu_threads)
        cpu_sim, _ = sim_on("cpu")
        step("cpu", lambda: dict(generations=a.short, threads=a.cpu_threads,
                                 per_arch_cpu=per_arch(lockstep(cpu_sim, a.short)),
                                 per_arch_device=per_arch(short["a"])))


if __name__ == "__main__":
    main()

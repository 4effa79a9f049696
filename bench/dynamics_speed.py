"""Ensemble rollouts for one CMA-ES generation (24 candidates x 48 targets, 3 seeds, 25 steps) and the
achieved GFLOP/s against a matmul peak measured in the same run.

    python bench/dynamics_speed.py [--threads N] [--device cpu|cuda] [--repeats R] [models/seed*.pt ...]

Times `Ensemble.rollout` (all seeds stacked, inputs and outputs as numpy, as policy search calls it).
Without model files, three freshly initialised models are timed (the cost does not depend on the
weights). FLOPs count the GRU and head matmuls only (2 per multiply-add); elementwise gate work is
extra, so the fraction of peak is a lower bound.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from embodied_snap.dynamics.model import HISTORY, HORIZON, LOOKAHEAD, N_U, N_X, Dynamics, load
from embodied_snap.dynamics.rollout import Ensemble


def rollout_flops(model: Dynamics, batch: int, horizon: int = HORIZON) -> float:
    H = model.gru.hidden_size
    per_step = sum(2 * 3 * H * (i + H) for i in (model.n_in, *[H] * (model.gru.num_layers - 1)))
    gru_steps = HISTORY + horizon - 1  # 20 encoding frames, then one carried step per prediction
    return batch * (gru_steps * per_step + horizon * 2 * H * N_X)


def matmul_peak(device: str, n: int = 2048, repeats: int = 10) -> float:
    a, b = torch.randn(n, n, device=device), torch.randn(n, n, device=device)
    best = np.inf
    for _ in range(repeats):
        sync(device)
        t = time.perf_counter()
        a @ b
        sync(device)
        best = min(best, time.perf_counter() - t)
    return 2 * n**3 / best / 1e9


def sync(device: str) -> None:
    if device == "cuda":
        torch.cuda.synchronize()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("models", nargs="*")
    ap.add_argument("--threads", type=int, default=torch.get_num_threads())
    ap.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--candidates", type=int, default=24)
    ap.add_argument("--targets", type=int, default=48)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    dev = a.device
    torch.manual_seed(0)
    if a.models:
        models = [load(p, dev) for p in a.models]
    else:
        stats = {k: np.ones(n, np.float32) if "sd" in k else np.zeros(n, np.float32)
                 for k, n in (("x_mu", N_X), ("x_sd", N_X), ("v_sd", N_X), ("u_mu", N_U), ("u_sd", N_U), ("r_sd", N_X))}
        models = [Dynamics(stats).to(dev).eval() for _ in range(3)]
    B = a.candidates * a.targets
    xs = torch.randn(B, HISTORY + 1, N_X, device=dev)
    us = torch.randn(B, HISTORY + HORIZON + LOOKAHEAD - 1, N_U, device=dev)
    ens = Ensemble(models=models, device=dev)  # the policy-search API, all seeds stacked
    ens.rollout(xs, us, HORIZON)  # warm-up
    times = []
    for _ in range(a.repeats):
        sync(dev)
        t = time.perf_counter()
        ens.rollout(xs, us, HORIZON)
        sync(dev)
        times.append(time.perf_counter() - t)
    gen = float(np.median(times))
    flops = len(models) * rollout_flops(models[0], B)
    peak = matmul_peak(dev)
    print(f"device {dev}, threads {a.threads}")
    print(f"generation: {a.candidates} x {a.targets} x {len(models)} seeds x {HORIZON} steps "
          f"in {gen:.3f} s (median of {a.repeats}; min {min(times):.3f} s)")
    print(f"ensemble rollouts/s: {len(models) * B / gen:,.0f}")
    print(f"achieved {flops / gen / 1e9:.1f} GFLOP/s of a measured {peak:.1f} GFLOP/s matmul peak "
          f"({100 * flops / gen / 1e9 / peak:.0f} %); {flops / 1e9:.2f} GFLOP per generation")


if __name__ == "__main__":
    main()

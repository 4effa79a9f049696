"""Ensemble rollouts for one CMA-ES generation (24 candidates x 48 targets, 3 seeds) and the achieved
GFLOP/s against a matmul peak measured in the same run, at horizon 25 (the issue's definition) and
72 (policy search: from before the S2 release to 0.75 s past the S1 release).

    python bench/dynamics_speed.py [--threads N] [--horizon H ...] [--device cpu|cuda] [--repeats R]
                                   [models/seed*.pt ...]

Times `Ensemble.rollout` (all seeds, inputs and outputs as numpy, as policy search calls it).
Without model files, three freshly initialised models are timed (the cost does not depend on the
weights). FLOPs count only the matmuls the math needs, 2 per multiply-add: per GRU step and layer
W_ih and W_hh for the r, z and n gates, 2 * 3H * (n_in + H) per row; 20 history steps plus
horizon - 1 carried ones; the head (2 * H * 21) once per prediction. Bias adds, the gates'
elementwise work and the frame normalisation are not counted, so the fraction of peak is a lower
bound. The peak is a 2048^3 sgemm on the same threads, best of 10, taken before and after the
rollouts; the higher one is used.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from embodied_snap.dynamics.model import N_U, N_X, Dynamics, load
from embodied_snap.dynamics.rollout import Ensemble

HISTORY, LOOKAHEAD = 20, 5  # the paper's windows (config `windows`): what the benchmark times


def rollout_flops(model: Dynamics, batch: int, horizon: int) -> float:
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
    ap.add_argument("--horizon", type=int, nargs="+", default=[25, 72])
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    dev = a.device
    torch.manual_seed(0)
    if a.models:
        models = [load(p, dev) for p in a.models]
    else:
        stats = {k: np.ones(n, np.float32) if "sd" in k else np.zeros(n, np.float32)
                 for k, n in (("x_mu", N_X), ("x_sd", N_X), ("v_sd", N_X), ("u_mu", N_U), ("u_sd", N_U), ("r_sd", N_X))}
        models = [Dynamics(stats, LOOKAHEAD).to(dev).eval() for _ in range(3)]
    B = a.candidates * a.targets
    ens = Ensemble(models=models, device=dev)  # the policy-search API
    peak = matmul_peak(dev)
    data = {}
    for horizon in a.horizon:
        xs = torch.randn(B, HISTORY + 1, N_X, device=dev).cpu().numpy()
        us = torch.randn(B, HISTORY + horizon + LOOKAHEAD - 1, N_U, device=dev).cpu().numpy()
        data[horizon] = xs, us
        ens.rollout(xs, us, horizon)  # warm-up
    times = {h: [] for h in a.horizon}
    for _ in range(a.repeats):  # horizons interleaved, so that both see the same machine
        for horizon, (xs, us) in data.items():
            sync(dev)
            t = time.perf_counter()
            ens.rollout(xs, us, horizon)
            sync(dev)
            times[horizon].append(time.perf_counter() - t)
    rows = [(h, float(np.median(t)), min(t), len(models) * rollout_flops(models[0], B, h)) for h, t in times.items()]
    peak = max(peak, matmul_peak(dev))
    print(f"device {dev}, threads {a.threads}; matmul peak {peak:.1f} GFLOP/s (2048^3 sgemm, best of 10)")
    for horizon, gen, best, flops in rows:
        rate = flops / gen / 1e9
        print(f"generation: {a.candidates} x {a.targets} x {len(models)} seeds x {horizon} steps in {gen:.3f} s "
              f"(median of {a.repeats}; min {best:.3f} s), {len(models) * B / gen:,.0f} rollouts/s; "
              f"{flops / 1e9:.2f} GFLOP, {rate:.1f} GFLOP/s = {100 * rate / peak:.0f} % of peak")


if __name__ == "__main__":
    main()

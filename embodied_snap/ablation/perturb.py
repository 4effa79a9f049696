"""Pre-release perturbation (paper V-B "Perturbing ..."): the selected policy's strikes when the
predicted pre-release configuration is off by multiples of the hold model's leave-one-session-out
error (results/dynamics/hold.json: median tip and tip-axis errors), over seeded draws."""

from __future__ import annotations

import numpy as np

from .rollouts import perturbation, rollout


def sweep(sim, act: dict, T, scales, draws: int, err_mm: float, err_deg: float, n_axis, seed: int,
          arm_mm: float) -> list[dict]:
    """Per scale (0 = unperturbed): median miss (mm, % of the arm), mean predicted peak speed,
    over all targets x draws (draws rolled out as one batch per scale)."""
    rng = np.random.default_rng(seed)
    N, out = len(T), []
    for s in [0.0, *scales]:
        m = 1 if s == 0 else draws
        a = {k: np.tile(np.asarray(v), m) for k, v in act.items()}
        pert = None if s == 0 else perturbation(rng, m * N, s * err_mm / 1e3, s * err_deg, n_axis)
        r = rollout(sim, a, np.tile(T.p, (m, 1)), np.tile(T.normal, (m, 1)), perturb=pert)
        miss = np.median(r["miss_m"]) * 1e3
        out.append(dict(scale=float(s), n=int(m * N), draws=m, pos_mm=s * err_mm, axis_deg=s * err_deg,
                        median_miss_mm=float(miss), median_miss_pct_arm=float(miss / arm_mm * 100),
                        mean_peak_speed=float(np.mean(r["v_pk_mps"]))))
    return out

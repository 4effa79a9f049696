"""Pre-release perturbation (paper V-B "Perturbing ..."): the selected policy's strikes when the
predicted pre-release configuration is off by multiples of the hold model's leave-one-session-out
error (results/dynamics/hold.json: median tip and tip-axis errors), over seeded draws."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rollouts import perturbation, rollout


@dataclass(frozen=True)
class PerturbationSweep:
    """The sweep's scales and draws, and the hold model's error they multiply (hold.json)."""

    scales: tuple[float, ...]  # multiples of the hold error; 0 (unperturbed) goes first on its own
    draws: int  # seeded draws per nonzero scale
    err_mm: float  # the hold model's median tip error (mm)
    err_deg: float  # its median tip-axis error (degrees)
    arm_mm: float  # the arm length misses are reported against (mm)
    seed: int  # seeds the draws


def sweep(sim, act: dict, targets, spec: PerturbationSweep, hanging_axis) -> list[dict]:
    """Per scale (0 = unperturbed): median miss (mm, % of the arm), mean predicted peak speed,
    over all targets x draws (draws rolled out as one batch per scale)."""
    rng = np.random.default_rng(spec.seed)
    n_targets, out = len(targets), []
    for scale in [0.0, *spec.scales]:
        n_draws = 1 if scale == 0 else spec.draws
        tiled = {k: np.tile(np.asarray(v), n_draws) for k, v in act.items()}
        pert = None if scale == 0 else perturbation(rng, n_draws * n_targets, scale * spec.err_mm / 1e3,
                                                    scale * spec.err_deg, hanging_axis)
        rolled = rollout(sim, tiled, np.tile(targets.p, (n_draws, 1)), np.tile(targets.normal, (n_draws, 1)),
                         perturb=pert)
        miss = np.median(rolled["miss_m"]) * 1e3
        out.append(dict(scale=float(scale), n=int(n_draws * n_targets), draws=n_draws, pos_mm=scale * spec.err_mm,
                        axis_deg=scale * spec.err_deg, median_miss_mm=float(miss),
                        median_miss_pct_arm=float(miss / spec.arm_mm * 100),
                        mean_peak_speed=float(np.mean(rolled["v_pk_mps"]))))
    return out

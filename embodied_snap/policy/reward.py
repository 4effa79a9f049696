"""Reward and attachment event (paper Eq. 9-11) of predicted strikes.

At closest approach (after the S1 release) the cup-face error l is projected onto the target plane
and g is its signed gap along the face normal; v_pk and t_pk are the peak tip speed and its time,
t_ca the closest-approach time; dt is the protocol's grid step.

    G = sig((d_f - |g|) / s_g),  A = G/2 sum_{q=a,b} exp(-l^2 / 2 s_q^2),
    S = sig((v_pk - v_min) / v_s),  H = exp(-(t_ca - t_pk)^2 / 2 s_t^2)            (Eq. 9)
    R = A S (1/2 + H/2) C_h min(1, P_snap / 0.5) - lambda mean(sigma_tip)           (Eq. 10)
    attached(r) = [l <= r, |g| <= d_f, v_pk >= v_min]                                (Eq. 11)
"""

from __future__ import annotations

import numpy as np


def sigmoid(z):
    return 1.0 / (1.0 + np.exp(-z))


def strike(cup: np.ndarray, tip: np.ndarray, p: np.ndarray, normal: np.ndarray, k_s1: np.ndarray, dt: float) -> dict:
    """cup, tip (N, K+1, 3) predicted (ensemble mean) on a grid of step dt; target p and unit face
    normal (N, 3); k_s1 (N,) the first step after the S1 release. Closest approach is searched from
    k_s1 on."""
    rel = cup - p[:, None]
    gap = (rel * normal[:, None]).sum(-1)
    lat = np.linalg.norm(rel - gap[..., None] * normal[:, None], axis=-1)
    dist = np.linalg.norm(rel, axis=-1)
    k = np.arange(cup.shape[1])
    k_ca = np.argmin(np.where(k[None] >= k_s1[:, None], dist, np.inf), 1)
    v = np.linalg.norm(np.diff(tip, axis=1), axis=-1) / dt  # speed over step k -> k+1
    k_pk = np.argmax(v, 1)
    i = np.arange(len(p))
    return dict(lateral_m=lat[i, k_ca], gap_m=gap[i, k_ca], miss_m=dist[i, k_ca],
                v_pk_mps=v[i, k_pk], t_pk_s=(k_pk + 0.5) * dt, t_ca_s=k_ca * dt)


def reward(s: dict, c_h, p_snap, disagreement, c: dict) -> np.ndarray:
    """Eq. 9-10 with the constants c (d_f, sigma_g, sigma_a, sigma_b, v_min, v_s, sigma_t, lambda)."""
    G = sigmoid((c["d_f_m"] - np.abs(s["gap_m"])) / c["sigma_g_m"])
    A = G / 2 * sum(np.exp(-s["lateral_m"] ** 2 / (2 * c[q] ** 2)) for q in ("sigma_a_m", "sigma_b_m"))
    S = sigmoid((s["v_pk_mps"] - c["v_min_sim_mps"]) / c["v_s_mps"])
    H = np.exp(-((s["t_ca_s"] - s["t_pk_s"]) ** 2) / (2 * c["sigma_t_s"] ** 2))
    return A * S * (0.5 + 0.5 * H) * c_h * np.minimum(1.0, p_snap / 0.5) - c["lambda_per_m"] * disagreement


def attached(lateral, gap, v_pk, r, d_f, v_min) -> np.ndarray:
    """Eq. 11 at lateral tolerance r."""
    return (lateral <= r) & (np.abs(gap) <= d_f) & (v_pk >= v_min)

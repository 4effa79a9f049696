"""The policy architectures of paper IV-B/IV-C (their table: architectures.py) as functions of a flat
parameter vector theta.

Every architecture returns the same six dimensionless outputs u in [-1, 1] per target, in the order
ACTIONS = (rho1, dphi, tau, rho2, rho3, s3).
- shared (155): one 6-8-8-3 tanh network (Eq. 6) evaluated once per section on [g_norm, one-hot i];
  section 1 gives (rho1, dphi, tau), section 2 rho2, section 3 (rho3, s3); unused outputs dropped.
- centralised (158) and centralised16 (438): one 3-h-h-6 tanh network on g_norm, h = 8 or 16.
- unshared (366): three local 3-8-8-k networks on g_norm, k = 3, 1, 2 outputs for S1, S2, S3.
"""

from __future__ import annotations

import numpy as np

from .architectures import BY_NAME, SECTION_OUTPUTS, TABLE

ACTIONS = ("rho1", "dphi", "tau", "rho2", "rho3", "s3")


# Layer sizes of each architecture's networks, from the architectures' table (architectures.py).
ARCHS = {a.name: a.nets for a in TABLE}


def n_params(arch: str) -> int:
    return sum(o * i + o for net in ARCHS[arch] for o, i in net)


INITS = ("zero", "glorot")


def initial(arch: str, start: dict, seed: int) -> np.ndarray:
    """theta where a search starts (`policy.start`, docs/policy.md "Starting point"):
    - zero: every weight and bias 0, so every architecture starts at mid-range commands;
    - glorot: each layer's weights uniform on +-sqrt(6 / (fan_in + fan_out)) (Glorot and Bengio 2010,
      the scale that keeps a tanh layer's activations and gradients at unit variance), biases 0;
      drawn from the start's init_seed and the run's seed, so each run starts elsewhere."""
    if start["init"] == "zero":
        return np.zeros(n_params(arch))
    assert start["init"] == "glorot", f"unknown start {start['init']!r}: one of {INITS}"
    rng = np.random.default_rng([start["init_seed"], seed])
    parts = []
    for net in ARCHS[arch]:
        for o, i in net:
            a = np.sqrt(6 / (i + o))
            parts += [rng.uniform(-a, a, o * i), np.zeros(o)]
    return np.concatenate(parts)


def _unpack(theta: np.ndarray, arch: str) -> list[list[tuple[np.ndarray, np.ndarray]]]:
    nets, k = [], 0
    for net in ARCHS[arch]:
        layers = []
        for o, i in net:
            W = theta[k:k + o * i].reshape(o, i)
            k += o * i
            layers.append((W, theta[k:k + o]))
            k += o
        nets.append(layers)
    assert k == len(theta), f"{arch}: theta has {len(theta)} parameters, the network {k}"
    return nets


def _forward(layers, x, tanh):
    for W, b in layers:
        x = tanh(x @ W.T + b)  # tanh on every layer, the output included (Eq. 6)
    return x


def outputs(arch: str, theta, g):
    """u (N, 6) in ACTIONS order for normalised target features g (N, 3). numpy arrays, or torch
    tensors (theta and g both: a least-squares fit differentiates it, `landscape.fit_architecture`)."""
    if type(theta).__module__.startswith("torch"):
        import torch as xp
    else:
        xp, theta = np, np.asarray(theta, float)
    nets = _unpack(theta, arch)
    sharing = BY_NAME[arch].sharing
    if sharing == "section_code":
        eye = xp.eye(3, dtype=g.dtype)
        u = [_forward(nets[0], xp.concatenate([g, xp.broadcast_to(eye[i], (len(g), 3))], 1), xp.tanh)
             for i in range(3)]
        return xp.concatenate([u[i][:, :k] for i, k in enumerate(SECTION_OUTPUTS)], 1)
    if sharing == "per_section":
        return xp.concatenate([_forward(net, g, xp.tanh) for net in nets], 1)
    assert sharing == "joint", f"{arch}: unknown sharing {sharing!r}"
    return _forward(nets[0], g, xp.tanh)

"""The dynamics model of paper Eq. 3-4: a GRU residual over the constant-velocity prior.

    x_{t+1} = f_cv(x_t, x_{t-1}) + F_psi(x_{t-19:t}, u_{t-19:t+5}),   f_cv = 2 x_t - x_{t-1}   (Eq. 3)

F_psi is a two-layer, width-96 GRU that reads one frame per step: at step k its input is the
normalised state x_k, the normalised velocity x_k - x_{k-1} and the commands u_{k..k+5}, so after
the 20 history steps k = t-19..t it has seen exactly x_{t-19:t} and u_{t-19:t+5}. The residual is
read from the last hidden state and scaled by the training-split spread of x_{t+1} - f_cv.

Rollout (Eq. 4) feeds each prediction back. `rollout(carry=True)` advances the GRU by one frame
per step and keeps its hidden state (45 GRU steps per 25-step rollout); `carry=False` re-encodes
the last 20 frames from a zero state at every step, literally F_psi(H_{t+h}, U_{t+h}) (500 GRU
steps). They differ only in what the carried state remembers from before t+h-19; training uses
the carried form and tests/test_dynamics.py measures the gap.

The window lengths are the protocol's (config `windows`), not this module's: the look-ahead is
fixed by the GRU's input width (so a saved model knows its own), the history is however many
frames a rollout is given.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

N_X, N_U = 21, 9
TIP = slice(6, 9)  # tip_x, tip_y, tip_z in STATE_COLUMNS (m, base frame)
AXIS = slice(9, 12)


def f_cv(x_t: torch.Tensor, x_prev: torch.Tensor) -> torch.Tensor:
    """Constant-velocity prior on every state component (positions, axis, servo positions)."""
    return 2 * x_t - x_prev


def norm_stats(X: np.ndarray, U: np.ndarray, group: np.ndarray) -> dict[str, np.ndarray]:
    """Normalisation from the TRAINING frames only: state, velocity, command and residual spread."""
    same = group[1:] == group[:-1]
    dx = (X[1:] - X[:-1])[same]
    # residual target of Eq. 3: x_{t+1} - (2 x_t - x_{t-1}) inside a group
    same2 = same[1:] & same[:-1]
    r = (X[2:] - 2 * X[1:-1] + X[:-2])[same2]
    eps = 1e-6
    return {
        "x_mu": X.mean(0),
        "x_sd": X.std(0) + eps,
        "v_sd": dx.std(0) + eps,
        "u_mu": U.mean(0),
        "u_sd": U.std(0) + eps,
        "r_sd": r.std(0) + eps,
    }


def lookahead_of(n_in: int) -> int:
    """The command look-ahead a GRU input width holds: frame = x, velocity, u_{k..k+lookahead}."""
    return (n_in - 2 * N_X) // N_U - 1


class Dynamics(nn.Module):
    def __init__(self, stats: dict, lookahead: int, width: int = 96, layers: int = 2):
        super().__init__()
        for k, v in stats.items():
            self.register_buffer(k, torch.as_tensor(np.asarray(v), dtype=torch.float32))
        self.lookahead = lookahead
        self.n_in = 2 * N_X + (lookahead + 1) * N_U
        self.gru = nn.GRU(self.n_in, width, layers, batch_first=True)
        self.head = nn.Linear(width, N_X)
        # Start at the prior: a zero residual is f_cv itself.
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def frame(self, x: torch.Tensor, x_prev: torch.Tensor, u_ahead: torch.Tensor) -> torch.Tensor:
        """GRU input for frames (..., 21), (..., 21), (..., lookahead+1, 9) -> (..., n_in)."""
        u = ((u_ahead - self.u_mu) / self.u_sd).flatten(-2)
        return torch.cat([(x - self.x_mu) / self.x_sd, (x - x_prev) / self.v_sd, u], -1)

    def step(self, x, x_prev, u_ahead, h=None):
        """One carried GRU step: next state (B, 21) and the new hidden state."""
        y, h = self.gru(self.frame(x, x_prev, u_ahead)[:, None], h)
        return f_cv(x, x_prev) + self.head(y[:, 0]) * self.r_sd, h

    def encode(self, xs: torch.Tensor, us: torch.Tensor, h=None):
        """Run the GRU over a history: xs (B, T+1, 21) with one frame before the first, us
        (B, T+lookahead, 9). Returns the prediction of the frame after xs[:, -1] and the hidden state."""
        T = xs.shape[1] - 1
        ua = us.unfold(1, self.lookahead + 1, 1)[:, :T].transpose(-1, -2)  # (B, T, 6, 9): u_{k..k+5}
        y, h = self.gru(self.frame(xs[:, 1:], xs[:, :-1], ua), h)
        return f_cv(xs[:, -1], xs[:, -2]) + self.head(y[:, -1]) * self.r_sd, h

    def rollout(self, xs: torch.Tensor, us: torch.Tensor, horizon: int, carry: bool = True):
        """Eq. 4 open loop. xs (B, history+1, 21): x_{t-20..t} (one frame before the history for its
        velocity); us (B, history+horizon+lookahead-1, 9): u_{t-19..t+horizon+4}. Returns
        x_hat_{t+1..t+horizon} (B, horizon, 21)."""
        history, lookahead = xs.shape[1] - 1, self.lookahead
        x_next, h = self.encode(xs, us[:, :history + lookahead])
        out = [x_next]
        hist = list(xs.unbind(1))
        for k in range(1, horizon):
            hist.append(x_next)
            if carry:
                x_next, h = self.step(hist[-1], hist[-2], us[:, history + k - 1:history + k + lookahead], h)
            else:
                win = torch.stack(hist[-history - 1:], 1)
                x_next, _ = self.encode(win, us[:, k:k + history + lookahead])
            out.append(x_next)
        return torch.stack(out, 1)


def n_params(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def save(model: Dynamics, path, **extra) -> None:
    torch.save({"state": model.state_dict(), **extra}, path)


def load(path, device="cpu") -> Dynamics:
    ck = torch.load(path, map_location=device, weights_only=True)  # tensors and plain data only
    stats = {k: ck["state"][k].cpu().numpy() for k in ("x_mu", "x_sd", "v_sd", "u_mu", "u_sd", "r_sd")}
    m = Dynamics(stats, lookahead_of(ck["state"]["gru.weight_ih_l0"].shape[1])).to(device)
    m.load_state_dict(ck["state"])
    return m.eval()

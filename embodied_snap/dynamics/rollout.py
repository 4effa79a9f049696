"""Ensemble rollouts for policy search: every seed's Eq. 4 rollout of a batch of start states.

A CMA-ES generation asks for (candidates x targets) rollouts, each from a start history (the hold
model's pre-release configuration) under a command schedule. All seeds are returned: the policy
reward uses their mean and penalises their disagreement.

The seeds run as one stacked computation: each GRU layer's weights of all seeds form one batched
matmul (torch.baddbmm over the seed axis), the 20 history frames' input projections are one matmul,
and the GRU state is carried from step to step, exactly as in training (Dynamics.rollout(carry=True);
tests/test_dynamics.py checks that the stacked path equals it and measures what re-encoding the
20-step window instead would change).
"""

from __future__ import annotations

import numpy as np
import torch

from .model import HISTORY, LOOKAHEAD, TIP, load


def default_device() -> str:
    return "cuda" if torch.cuda.is_available() else "cpu"


class Ensemble:
    def __init__(self, paths=(), device: str | None = None, models=None):
        self.device = device or default_device()
        self.models = list(models) if models is not None else [load(p, self.device) for p in paths]
        ms = self.models
        st = lambda f: torch.stack([f(m) for m in ms]).to(self.device)  # noqa: E731
        g = ms[0].gru
        self.H, self.layers = g.hidden_size, g.num_layers
        # Per layer: W_ih^T (S, in, 3H), W_hh^T (S, H, 3H), biases (S, 1, 3H); gate order r, z, n.
        self.w_ih = [st(lambda m: getattr(m.gru, f"weight_ih_l{k}").T) for k in range(self.layers)]
        self.w_hh = [st(lambda m: getattr(m.gru, f"weight_hh_l{k}").T) for k in range(self.layers)]
        self.b_ih = [st(lambda m: getattr(m.gru, f"bias_ih_l{k}")[None]) for k in range(self.layers)]
        self.b_hh = [st(lambda m: getattr(m.gru, f"bias_hh_l{k}")[None]) for k in range(self.layers)]
        self.w_out = st(lambda m: m.head.weight.T * m.r_sd)  # the residual scale folded in
        self.b_out = st(lambda m: (m.head.bias * m.r_sd)[None])
        self.s = {k: st(lambda m: getattr(m, k)[None]) for k in ("x_mu", "x_sd", "v_sd", "u_mu", "u_sd")}

    def _frame(self, x, x_prev, u_ahead):
        """(S, B, [T,] 21) x2, (B, [T,] 6, 9) -> (S, B, [T,] n_in), each seed with its statistics."""
        e = (1,) * (x.ndim - 2)
        s = {k: v.reshape(v.shape[0], *e, v.shape[-1]) for k, v in self.s.items()}
        u = ((u_ahead[None] - s["u_mu"][..., None, :]) / s["u_sd"][..., None, :]).flatten(-2)
        return torch.cat([(x - s["x_mu"]) / s["x_sd"], (x - x_prev) / s["v_sd"], u], -1)

    def _cell(self, k, gi, h):
        gh = torch.baddbmm(self.b_hh[k], h, self.w_hh[k])
        H = self.H
        rz = torch.sigmoid(gi[..., :2 * H] + gh[..., :2 * H])
        n = torch.tanh(torch.addcmul(gi[..., 2 * H:], rz[..., :H], gh[..., 2 * H:]))
        return torch.addcmul(n, rz[..., H:], h - n)  # (1 - z) n + z h

    def _step(self, inp, h):
        """One carried GRU step of all seeds and layers: inp (S, B, n_in), h [layers x (S, B, H)]."""
        out = []
        for k in range(self.layers):
            inp = self._cell(k, torch.baddbmm(self.b_ih[k], inp, self.w_ih[k]), h[k])
            out.append(inp)
        return torch.baddbmm(self.b_out, inp, self.w_out), out

    @torch.inference_mode()
    def rollout(self, xs, us, horizon: int = 25) -> dict[str, np.ndarray]:
        """xs (..., 21, 21): x_{t-20..t}; us (..., 20+horizon+4, 9): u_{t-19..t+horizon+4}; any
        leading batch shape, e.g. (candidates, targets). Returns tip (seeds, ..., horizon+1, 3)
        from x_t on, their mean, and disagreement = the per-step mean distance of the seeds' tips
        to the ensemble mean (m)."""
        xs = torch.as_tensor(np.asarray(xs, np.float32), device=self.device)
        us = torch.as_tensor(np.asarray(us, np.float32), device=self.device)
        lead = xs.shape[:-2]
        xs, us = xs.reshape(-1, *xs.shape[-2:]), us.reshape(-1, *us.shape[-2:])
        S, B = len(self.models), xs.shape[0]
        h = [xs.new_zeros(S, B, self.H) for _ in range(self.layers)]
        # History: the first layer's input projections of all 20 frames in one matmul.
        ua = us[:, :HISTORY + LOOKAHEAD].unfold(1, LOOKAHEAD + 1, 1).transpose(-1, -2)  # (B, 20, 6, 9)
        fr = self._frame(xs[None, :, 1:].expand(S, -1, -1, -1), xs[None, :, :-1].expand(S, -1, -1, -1), ua)
        gi0 = torch.baddbmm(self.b_ih[0], fr.reshape(S, B * HISTORY, -1), self.w_ih[0]).reshape(S, B, HISTORY, -1)
        for j in range(HISTORY):
            h[0] = self._cell(0, gi0[:, :, j], h[0])
            inp = h[0]
            for k in range(1, self.layers):
                h[k] = self._cell(k, torch.baddbmm(self.b_ih[k], inp, self.w_ih[k]), h[k])
                inp = h[k]
        x_prev, x = xs[None, :, -2].expand(S, -1, -1), xs[None, :, -1].expand(S, -1, -1)
        x_next = 2 * x - x_prev + torch.baddbmm(self.b_out, inp, self.w_out)  # Eq. 3
        tips = [x[..., TIP], x_next[..., TIP]]
        for k in range(1, horizon):
            x_prev, x = x, x_next
            res, h = self._step(self._frame(x, x_prev, us[:, HISTORY + k - 1:HISTORY + k + LOOKAHEAD]), h)
            x_next = 2 * x - x_prev + res  # Eq. 4
            tips.append(x_next[..., TIP])
        tip = torch.stack(tips, 2)  # (S, B, H+1, 3)
        mean = tip.mean(0)
        dis = (tip - mean).norm(dim=-1).mean(0)
        return {
            "tip": tip.reshape(S, *lead, horizon + 1, 3).cpu().numpy(),
            "mean": mean.reshape(*lead, horizon + 1, 3).cpu().numpy(),
            "disagreement": dis.reshape(*lead, horizon + 1).cpu().numpy(),
        }

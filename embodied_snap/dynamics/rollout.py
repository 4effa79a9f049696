"""Ensemble rollouts for policy search: every seed's Eq. 4 rollout of a batch of start states.

A CMA-ES generation asks for (candidates x targets) rollouts, each from a start history (the hold
model's pre-release configuration) under a command schedule. All seeds are returned: the policy
reward uses their mean and penalises their disagreement.

Each seed is the carried-state GRU of training (Dynamics.rollout(carry=True): 20 history frames,
then one step per prediction); tests/test_dynamics.py and tests/test_rollout.py check that this
path equals it. A rollout is a chain of small matmuls and gate nonlinearities, so the fast path is
about memory traffic and the number of ops:

- Seeds run one after the other, each over the whole batch: one seed's weights and state stay in
  cache for all steps (one bmm over the stacked seeds was ~20 % slower on 2 CPU cores).
- One buffer per seed holds a step's GRU inputs, Z = [frame | 1 | h_0 | 1 | h_1], and each gate
  block is one torch.mm on a column range of it: the r,z gates read [in | 1 | h] (input and hidden
  projections summed inside the matmul, biases through the ones column); the n gate's halves read
  [in | 1] and [1 | h], as it needs r * (W_hn h + b_hn). No FLOP goes to zero blocks.
- The gates work in place on preallocated buffers, h is updated in Z by torch.lerp, the states are
  written straight into the output, and each step's normalised frame (history frames too) is
  written into Z: nothing of size batch x steps is built besides the returned states.
- tanh(a) = 2 sigmoid(2a) - 1, the 2 folded into the n-gate weights (exact in floating point):
  torch's CPU tanh costs ~3x its sigmoid here.

Measured and dropped: torch.compile of the gates or of a whole step (the fused kernel is bound by
the same exp calls, within 3 % of the in-place ops, for 5-10 s of compilation); one K=193 matmul per
layer with zero blocks; one wider matmul per hidden state feeding the next layer and the next
step; splitting the batch over two Python threads at one intra-op thread each.
"""

from __future__ import annotations

import numpy as np
import torch

from .device import resolve
from .model import TIP, load


class Ensemble:
    def __init__(self, paths=(), device: str | None = None, models=None):
        # config policy.device where a job passes it (for_job); CPU otherwise. "cuda" without a
        # GPU falls back to CPU with one log line.
        self.device = resolve(device or "cpu", key="policy.device")
        self.models = list(models) if models is not None else [load(p, self.device) for p in paths]
        g = self.models[0].gru
        self.H, self.layers, self.n_in = g.hidden_size, g.num_layers, g.input_size
        self.lookahead = self.models[0].lookahead
        H = self.H
        # Z columns: h_k starts at off[k], with a ones column just before it.
        self.off = [self.n_in + 1 + k * (H + 1) for k in range(self.layers)]
        self.width = -(-(self.off[-1] + H) // 16) * 16  # rows padded to 64 bytes for the matmuls
        self.params = [self._pack(m) for m in self.models]

    @torch.no_grad()
    def _pack(self, m) -> dict:
        """One seed's weights as the column blocks of Z expect them (see the module docstring)."""
        H, one = self.H, lambda b: b[None]  # noqa: E731
        p = {"gates": []}
        for k in range(self.layers):
            wi, wh = getattr(m.gru, f"weight_ih_l{k}").T, getattr(m.gru, f"weight_hh_l{k}").T
            bi, bh = getattr(m.gru, f"bias_ih_l{k}"), getattr(m.gru, f"bias_hh_l{k}")
            rz = torch.cat([wi[:, :2 * H], one(bi[:2 * H] + bh[:2 * H]), wh[:, :2 * H]])
            n_i = 2 * torch.cat([wi[:, 2 * H:], one(bi[2 * H:])])  # x2: tanh(a) = 2 sigmoid(2a) - 1
            n_h = 2 * torch.cat([one(bh[2 * H:]), wh[:, 2 * H:]])
            p["gates"].append([w.contiguous().to(self.device) for w in (rz, n_i, n_h)])
        p["head"] = (torch.cat([one(m.head.bias), m.head.weight.T]) * m.r_sd).contiguous().to(self.device)
        rep = self.lookahead + 1  # the frame holds u_{k..k+5}
        p.update(x_mu=m.x_mu, x_sd=m.x_sd, v_sd=m.v_sd, u_mu=m.u_mu.repeat(rep), u_sd=m.u_sd.repeat(rep))
        return {k: v.to(self.device) if torch.is_tensor(v) else v for k, v in p.items()}

    @torch.inference_mode()
    def rollout(self, xs, us, horizon: int, states: bool = False, parts=()) -> dict:
        """xs (..., history+1, 21): x_{t-20..t}; us (..., history+horizon+lookahead-1, 9):
        u_{t-19..t+horizon+4}; any
        leading batch shape, e.g. (candidates, targets). Returns tip (seeds, ..., horizon+1, 3)
        from x_t on, their mean, and disagreement = the per-step mean distance of the seeds' tips
        to the ensemble mean (m). Optional: states=True adds the full states (seeds, ...,
        horizon+1, 21); parts, state column slices such as (TIP, AXIS), adds mean_parts, the
        ensemble mean of each (..., horizon+1, width)."""
        xs = torch.as_tensor(np.asarray(xs, np.float32), device=self.device)
        us = torch.as_tensor(np.asarray(us, np.float32), device=self.device)
        lead = xs.shape[:-2]
        xs, us = xs.reshape(-1, *xs.shape[-2:]), us.reshape(-1, *us.shape[-2:])
        S = len(self.models)
        out = xs.new_empty(S, horizon + 1, xs.shape[0], xs.shape[-1])  # step-major: each step one block
        for s, p in enumerate(self.params):
            self._seed(p, xs, us, out[s])
        mean = out.mean(0)  # (horizon+1, B, 21): the seed means of whole contiguous rows, once
        out = out.transpose(1, 2)  # (S, B, horizon+1, 21)
        tip = out[..., TIP]
        # on the transposed view, as the rewards were first computed: the norm's sum depends on layout
        dis = (tip - tip.mean(0)).norm(dim=-1).mean(0)
        mean = mean.transpose(0, 1)
        res = {
            "tip": tip.reshape(S, *lead, horizon + 1, 3).cpu().numpy(),
            "mean": mean[..., TIP].reshape(*lead, horizon + 1, 3).cpu().numpy(),
            "disagreement": dis.reshape(*lead, horizon + 1).cpu().numpy(),
        }
        if states:
            res["states"] = out.reshape(S, *lead, horizon + 1, -1).cpu().numpy()
        if parts:
            res["mean_parts"] = [mean[..., sl].reshape(*lead, horizon + 1, -1).cpu().numpy() for sl in parts]
        return res

    def _seed(self, p: dict, xs, us, out) -> None:
        """One seed's rollout of the whole batch into out (horizon+1, B, 21)."""
        B, nx, H, off = xs.shape[0], xs.shape[-1], self.H, self.off
        history, lookahead = xs.shape[1] - 1, self.lookahead  # the history is what the caller gives
        Z = xs.new_zeros(B, self.width)
        Z[:, [o - 1 for o in off]] = 1
        rz, n_i, n_h = xs.new_empty(B, 2 * H), xs.new_empty(B, H), xs.new_empty(B, H)
        # Per layer: the matmul inputs [in | 1 | h], [in | 1], [1 | h] and h, as views of Z.
        views = [(Z[:, lo:q + H], Z[:, lo:q], Z[:, q - 1:q + H], Z[:, q:q + H]) for lo, q in zip([0, *off], off)]
        last = views[-1][2]
        fx, fv, fu = Z[:, :nx], Z[:, nx:2 * nx], Z[:, 2 * nx:self.n_in]
        res = xs.new_empty(B, nx)
        out[0] = xs[:, -1]
        x, xp = out[0], xs[:, -2]
        for j in range(history + len(out) - 2):
            # The frame of step j: the history's own frames first, then the fed-back predictions.
            a, b = (xs[:, j + 1], xs[:, j]) if j < history else (x, xp)
            torch.sub(a, p["x_mu"], out=fx).div_(p["x_sd"])
            torch.sub(a, b, out=fv).div_(p["v_sd"])
            torch.sub(us[:, j:j + lookahead + 1].reshape(B, -1), p["u_mu"], out=fu).div_(p["u_sd"])  # u_{j..j+5}
            for (zrz, zi, zh, h), (w_rz, w_ni, w_nh) in zip(views, p["gates"]):
                torch.mm(zrz, w_rz, out=rz)
                torch.mm(zi, w_ni, out=n_i)
                torch.mm(zh, w_nh, out=n_h)
                rz.sigmoid_()
                n = n_i.addcmul_(rz[:, :H], n_h).sigmoid_().mul_(2).sub_(1)
                torch.lerp(n, h, rz[:, H:], out=h)  # (1 - z) n + z h, in place in Z
            if j >= history - 1:
                k = j - history + 2
                torch.mm(last, p["head"], out=res)
                torch.mul(x, 2, out=out[k]).sub_(xp).add_(res)  # Eq. 3-4: f_cv + residual
                xp, x = x, out[k]

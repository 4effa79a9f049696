"""Training of Eq. 3 on H-step open-loop rollouts (Eq. 4; H = 25 in the paper), paper IV-A.

Loss: normalised MSE of the rolled-out states, step weights proportional to h^-1/2 (h = 1..H),
window factors 5 (snap) and 3 (fast motion). Early stopping and model selection use the
validation windows only; the sealed windows never come near this module. History, look-ahead and
horizon are the windows' own (windows.py stores them with the arrays).
"""

from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch

from .device import resolve
from .model import TIP, Dynamics, norm_stats

SNAP_FACTOR, FAST_FACTOR = 5.0, 3.0


def step_weights(horizon: int) -> torch.Tensor:
    """w_h proportional to h^-1/2, mean 1, so the loss stays on the scale of a per-step MSE."""
    w = torch.arange(1, horizon + 1, dtype=torch.float32) ** -0.5
    return w / w.mean()


def window_factors(snap: np.ndarray, fast: np.ndarray) -> np.ndarray:
    """5 on snap windows, 3 on fast ones (windows.py makes them exclusive), 1 otherwise."""
    return np.where(snap, SNAP_FACTOR, np.where(fast, FAST_FACTOR, 1.0)).astype(np.float32)


def group_start(group: np.ndarray) -> np.ndarray:
    """Row index of each row's group start: the history's first velocity stays inside its group."""
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    return starts[np.searchsorted(starts, np.arange(len(group)), side="right") - 1]


def batch(W: dict, anchors: np.ndarray, horizon: int | None = None):
    """Tensors of a rollout from anchors t: xs x_{t-20..t} (B, 21, 21), us u_{t-19..t+H+4},
    targets x_{t+1..t+H} (H: the windows' horizon unless given). The frame before the history
    repeats x_{t-19} at a group's first anchor."""
    history, lookahead = int(W["history"]), int(W["lookahead"])
    horizon = int(W["horizon"]) if horizon is None else horizon
    a = np.asarray(anchors)[:, None]
    g0 = W["_start"][a[:, 0]][:, None]
    xi = np.maximum(a + np.arange(-history, 1), g0)
    ui = a + np.arange(-history + 1, horizon + lookahead)
    ti = a + np.arange(1, horizon + 1)
    X, U = W["X"], W["U"]
    return torch.from_numpy(X[xi]), torch.from_numpy(U[ui]), torch.from_numpy(X[ti])


def _on(device, *ts):
    return [t.to(device) for t in ts]


def prepare(W: dict) -> dict:
    W = dict(W)
    W["_start"] = group_start(W["group"])
    W["factor"] = window_factors(W["snap"], W["fast"])
    return W


def rollout_loss(model: Dynamics, W: dict, idx: np.ndarray, wh: torch.Tensor) -> torch.Tensor:
    xs, us, y, f = _on(wh.device, *batch(W, W["anchors"][idx]), torch.from_numpy(W["factor"][idx]))
    pred = model.rollout(xs, us, y.shape[1])
    e = ((pred - y) / model.x_sd) ** 2  # normalised squared error (B, H, 21)
    per = (e.mean(-1) * wh).mean(-1)  # (B,)
    return (per * f).sum() / f.sum()


@torch.no_grad()
def evaluate_loss(model, W, idx, wh, bs=1024):
    """Weighted loss and mean tip error at h = H (mm) over fixed validation windows."""
    num = den = tip = 0.0
    for i in range(0, len(idx), bs):
        j = idx[i:i + bs]
        xs, us, y, f = _on(wh.device, *batch(W, W["anchors"][j]), torch.from_numpy(W["factor"][j]))
        pred = model.rollout(xs, us, y.shape[1])
        e = ((pred - y) / model.x_sd) ** 2
        num += float(((e.mean(-1) * wh).mean(-1) * f).sum())
        den += float(f.sum())
        tip += float((pred[:, -1, TIP] - y[:, -1, TIP]).norm(dim=-1).sum()) * 1e3
    return num / den, tip / len(idx)


def seed_all(seed: int) -> None:
    torch.manual_seed(seed)
    torch.use_deterministic_algorithms(True)


@dataclass(frozen=True)
class TrainSettings:
    """Sizes and optimiser settings of one fit (config `dynamics` and the budget's `dynamics`)."""

    epochs: int  # the most epochs, and the cosine schedule's length
    windows_per_epoch: int  # training windows drawn (without replacement) per epoch
    val_windows: int  # the fixed validation windows scored after each epoch
    batch_size: int  # windows per optimiser step
    lr: float  # Adam's initial learning rate
    patience: int  # epochs without a better validation loss before training stops
    device: str = "cpu"  # config dynamics.device; device.resolve falls back to CPU


def train(Wtr: dict, Wva: dict, seed: int, settings: TrainSettings, *, log=print) -> tuple[Dynamics, list[dict]]:
    """Fit one seed with `settings` on its device. Returns the model of the best validation epoch,
    on CPU, and the learning curve."""
    epochs, windows_per_epoch, batch_size = settings.epochs, settings.windows_per_epoch, settings.batch_size
    device = resolve(settings.device, log)
    seed_all(seed)
    rng = np.random.default_rng(seed)
    Wtr, Wva = prepare(Wtr), prepare(Wva)
    # Normalisation from the training split only; the look-ahead is the windows'.
    model = Dynamics(norm_stats(Wtr["X"], Wtr["U"], Wtr["group"]), int(Wtr["lookahead"])).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=settings.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    wh = step_weights(int(Wtr["horizon"])).to(device)
    # The same validation windows for every seed and epoch (seeded apart from the model seed).
    nva = len(Wva["anchors"])
    val_idx = np.sort(np.random.default_rng(0).choice(nva, min(settings.val_windows, nva), replace=False))
    best, best_state, bad, curve = np.inf, None, 0, []
    t0 = time.perf_counter()
    for ep in range(1, epochs + 1):
        model.train()
        idx = rng.permutation(len(Wtr["anchors"]))[:windows_per_epoch]
        tot = 0.0
        for i in range(0, len(idx), batch_size):
            loss = rollout_loss(model, Wtr, idx[i:i + batch_size], wh)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            tot += float(loss.detach()) * len(idx[i:i + batch_size])
        sched.step()
        model.eval()
        vl, vtip = evaluate_loss(model, Wva, val_idx, wh)
        row = dict(epoch=ep, train_loss=tot / len(idx), val_loss=vl, val_tip_mm_h25=vtip,
                   seconds=time.perf_counter() - t0)
        curve.append(row)
        log(row)
        if vl < best:
            best, bad = vl, 0
            best_state = {k: v.clone() for k, v in model.state_dict().items()}
        else:
            bad += 1
            if bad >= settings.patience:
                break
    model.load_state_dict(best_state)
    return model.cpu().eval(), curve


_SIDE_BY_SIDE: dict = {}  # what the forked seeds share (the windows are not copied through a pipe)


def _train_forked(seed: int) -> tuple[Dynamics, list[dict]]:
    a = _SIDE_BY_SIDE
    torch.set_num_threads(a["threads"])
    return train(a["Wtr"], a["Wva"], seed, a["settings"], log=lambda r: a["log"](seed, r))


def train_seeds(Wtr: dict, Wva: dict, seeds: list[int], settings: TrainSettings, *, log,
                threads: int = 1) -> list[tuple[Dynamics, list[dict]]]:
    """train() for each seed, all at once: one forked process per seed with `threads` torch threads
    (config dynamics.seeds_in_one_job). Three seeds on two cores then end together, where three
    one-core jobs leave a core idle while the third trains alone (docs/benchmarks.md). Each seed's
    model is the one train() gives it alone. On a GPU (or with one seed) they train in turn, in this
    process: CUDA does not survive a fork. `log(seed, row)` gets each epoch's row."""
    if settings.device != "cpu" or len(seeds) == 1:
        torch.set_num_threads(threads)
        return [train(Wtr, Wva, s, settings, log=lambda r, s=s: log(s, r)) for s in seeds]
    _SIDE_BY_SIDE.update(Wtr=Wtr, Wva=Wva, threads=threads, log=log, settings=settings)
    try:
        with ProcessPoolExecutor(len(seeds), mp_context=multiprocessing.get_context("fork")) as pool:
            return list(pool.map(_train_forked, seeds))
    finally:
        _SIDE_BY_SIDE.clear()

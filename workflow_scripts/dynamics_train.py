"""Eq. 3-4 for one seed: train on the training windows, select on the validation windows."""

from embodied_snap.lineage import records  # noqa: F401 -- first, so every read of the job is watched

# isort: split

import sys

import pandas as pd
import torch

from embodied_snap.dynamics.model import n_params, save
from embodied_snap.dynamics.train import train
from embodied_snap.lineage.records import tracked
from embodied_snap.windows import load_windows

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    torch.set_num_threads(snakemake.threads)
    p = snakemake.params
    model, curve = train(
        load_windows(snakemake.input.train),
        load_windows(snakemake.input.validation),
        seed=p.seed, epochs=p.epochs, windows_per_epoch=p.windows_per_epoch, val_windows=p.val_windows,
        batch_size=p.batch_size, lr=p.lr, patience=p.patience, device=p.device,
        log=lambda r: print(r, file=sys.stderr, flush=True),
    )
    best = min(curve, key=lambda r: r["val_loss"])
    print(f"seed {p.seed}: {n_params(model)} parameters, selected epoch {best['epoch']}", file=sys.stderr)
    save(model, snakemake.output.model, seed=p.seed, selected_epoch=best["epoch"])
    pd.DataFrame(curve).to_csv(snakemake.output.curve, index=False, lineterminator="\n")

"""Eq. 3-4 for one seed, or for every seed side by side (config dynamics.seeds_in_one_job): train on
the training windows, select on the validation windows."""

import sys

import pandas as pd

from embodied_snap.dynamics.model import n_params, save
from embodied_snap.dynamics.train import TrainSettings, train_seeds
from embodied_snap.lineage.records import tracked
from embodied_snap.windows import load_windows


def each(x):
    return [x] if isinstance(x, (int, str)) else list(x)


sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    p = snakemake.params
    seeds = each(p.seed)
    fits = train_seeds(
        load_windows(snakemake.input.train),
        load_windows(snakemake.input.validation),
        seeds,
        TrainSettings(epochs=p.epochs, windows_per_epoch=p.windows_per_epoch, val_windows=p.val_windows,
                      batch_size=p.batch_size, lr=p.lr, patience=p.patience, device=p.device),
        threads=max(1, snakemake.threads // len(seeds)),
        log=lambda seed, r: print(f"seed {seed}: {r}", file=sys.stderr, flush=True),
    )
    for seed, (model, curve), out, curve_out in zip(seeds, fits, each(snakemake.output.model),
                                                     each(snakemake.output.curve)):
        best = min(curve, key=lambda r: r["val_loss"])
        print(f"seed {seed}: {n_params(model)} parameters, selected epoch {best['epoch']}", file=sys.stderr)
        save(model, out, seed=seed, selected_epoch=best["epoch"])
        pd.DataFrame(curve).to_csv(curve_out, index=False, lineterminator="\n")

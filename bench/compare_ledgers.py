"""Two runs' claims ledgers side by side: for a round trip (the simulated rig's recordings exported
as a lab's files and imported back) against the native run, claim by claim.

    python bench/compare_ledgers.py NATIVE/results/tables/claims.csv IMPORTED/results/tables/claims.csv

Prints, per stage, how many claims are identical, how many differ and by how much (relative to
the native value), then every differing claim: native, imported, relative difference. Exits 1 if
the two ledgers do not list the same claims.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd


def compare(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    m = a.merge(b, on="claim_id", suffixes=("_native", "_import"))
    x = pd.to_numeric(m.ours_native, errors="coerce")
    y = pd.to_numeric(m.ours_import, errors="coerce")
    same = (m.ours_native.astype(str) == m.ours_import.astype(str)) | (x == y)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(same, 0.0, np.abs(y - x) / np.abs(x))
    return m.assign(same=same, rel=rel)[["claim_id", "stage_native", "unit_native", "ours_native", "ours_import",
                                         "same", "rel"]]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("native")
    ap.add_argument("imported")
    a = ap.parse_args(argv)
    na, im = pd.read_csv(a.native, dtype={"ours": str}), pd.read_csv(a.imported, dtype={"ours": str})
    missing = sorted(set(na.claim_id) ^ set(im.claim_id))
    c = compare(na, im)
    print("| stage | claims | identical | differ | median rel. difference of those | max |")
    print("|---|---|---|---|---|---|")
    for stage, g in c.groupby("stage_native", sort=True):
        d = g[~g.same]
        med = f"{np.nanmedian(d.rel):.2%}" if len(d) else "-"
        mx = f"{np.nanmax(d.rel):.2%}" if len(d) else "-"
        print(f"| {stage} | {len(g)} | {int(g.same.sum())} | {len(d)} | {med} | {mx} |")
    print(f"\n{len(c)} claims: {int(c.same.sum())} identical, {int((~c.same).sum())} differ\n")
    for r in c[~c.same].sort_values(["stage_native", "rel"]).itertuples():
        print(f"{r.stage_native:14s} {r.claim_id:48s} {str(r.ours_native):>14s} {str(r.ours_import):>14s} {r.rel:8.2%} "
              f"{r.unit_native}")
    if missing:
        print(f"claims in one ledger only: {', '.join(missing)}")
        sys.exit(1)


if __name__ == "__main__":
    main()

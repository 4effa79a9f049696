"""Two runs' claims ledgers side by side: for a round trip (the simulated rig's recordings exported
as a lab's files and imported back) against the native run, claim by claim.

    python bench/compare_ledgers.py NATIVE/results/tables/claims.csv IMPORTED/results/tables/claims.csv

Prints, per stage, how many claims are identical, how many differ and by how much (relative to
the native value), then every differing claim: native, imported, relative difference; then every
mean over seeds that has its SD and seed count in the ledger (`<x>_mean`, `<x>_sd`, `seeds_<arch>`)
against its seed spread: z = (imported - native) / (sd sqrt(2 / n)), the difference of two means of
n seeds in units of its own standard error (|z| < 2 in about 95 % of two independent runs). Exits 1
if the two ledgers do not list the same claims.
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


def seed_spread(c: pd.DataFrame) -> pd.DataFrame:
    """Each `<x>_mean` claim with its `<x>_sd` (native) and n seeds (`seeds_<arch>`, its last word)."""
    v = c.set_index("claim_id")
    rows = []
    for cid in v.index[v.index.str.endswith("_mean")]:
        sd, arch = cid[: -len("_mean")] + "_sd", cid[: -len("_mean")].rsplit("_", 1)[-1]
        if sd not in v.index or f"seeds_{arch}" not in v.index:
            continue
        x, y = (pd.to_numeric(v.at[cid, k], errors="coerce") for k in ("ours_native", "ours_import"))
        s, n = pd.to_numeric(v.at[sd, "ours_native"], errors="coerce"), pd.to_numeric(
            v.at[f"seeds_{arch}", "ours_native"], errors="coerce")
        se = s * np.sqrt(2 / n) if n and n > 1 else np.nan
        rows.append(dict(claim_id=cid, native=x, imported=y, sd=s, n=n, z=(y - x) / se if se else np.nan))
    return pd.DataFrame(rows)


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
    z = seed_spread(c)
    if len(z):
        print(f"\nmeans over seeds against their spread (|z| < 2: {int((z.z.abs() < 2).sum())} of {len(z)})")
        for r in z.itertuples():
            print(f"{r.claim_id:48s} {r.native:10.4g} {r.imported:10.4g} sd {r.sd:8.3g} n {r.n:g}  z {r.z:+.2f}")
    if missing:
        print(f"claims in one ledger only: {', '.join(missing)}")
        sys.exit(1)


if __name__ == "__main__":
    main()

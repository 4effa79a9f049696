"""Are two runs' results the same, byte for byte? For a change that must not move any result.

    python bench/compare_runs.py RESULTS_A RESULTS_B [--all]

Compares every file under the two `results/` trees that a result is made of: claims tables, the
paper's tables, figures (saved without time stamps), models, policy runs and evaluations, the
50 Hz shards, the validation records and the stages' summaries. Provenance records, the report,
the RO-Crate and the lineage exports are left out: they name times and paths by design. Prints
one line per differing or missing file and a count per kind; exits 1 if anything differs.
--all lists the identical files too.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from collections import Counter
from pathlib import Path

SKIP = ("provenance/", "report", "crate/", "lineage/")


def kind(rel: str) -> str:
    if rel.endswith("claims.csv"):
        return "claims table"
    if rel.startswith(("figs/", "figures/")):
        return "figure"
    if rel.startswith("tables/"):
        return "table"
    if rel.endswith((".pt", ".npz", ".pkl")):
        return "model or array"
    return Path(rel).suffix.lstrip(".") or "other"


def files(root: Path) -> dict[str, Path]:
    out = {}
    for p in root.rglob("*"):
        rel = p.relative_to(root).as_posix()
        if p.is_file() and not rel.startswith(SKIP) and not p.name.startswith("."):
            out[rel] = p
    return out


def digest(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a", type=Path)
    ap.add_argument("b", type=Path)
    ap.add_argument("--all", action="store_true")
    a = ap.parse_args(argv)
    fa, fb = files(a.a), files(a.b)
    same, differ = Counter(), Counter()
    for rel in sorted(set(fa) | set(fb)):
        k = kind(rel)
        if rel not in fa or rel not in fb:
            differ[k] += 1
            print(f"only in {a.a if rel in fa else a.b}: {rel}")
        elif digest(fa[rel]) == digest(fb[rel]):
            same[k] += 1
            if a.all:
                print(f"identical: {rel}")
        else:
            differ[k] += 1
            print(f"differs: {rel}")
    for k in sorted(set(same) | set(differ)):
        print(f"{k}: {same[k]} identical, {differ[k]} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())

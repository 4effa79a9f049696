"""The ablation's two target sets (paper V-B, Table I "Release targets"): offset targets (the
event offsets are fitted on them) and release-evaluation targets (the rules are compared on them),
each from its own seed, disjoint from each other and from the policy's sets.

A target family is one recorded strike point of the workspace; its starts are targets drawn about
it as policy.targets.sample draws them (jitter, a bearing on the evaluated arc). The policy sees a
target in the canonical bearing (Eq. 5), where a family's starts differ only by the jitter: they
are repeated starts of one strike geometry (docs/ablation.md "Target family and start").
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import bearing as BR
from ..policy.targets import target_id


def sample_families(ws: dict, n_targets: int, starts: int, seed: int, arc_deg: float,
                    jitter_m: float) -> pd.DataFrame:
    """n_targets targets in families of `starts` (the last family may be smaller): each family a
    random strike point (without replacement while there are enough), each start that point +
    N(0, jitter) per axis turned to a bearing uniform on arc_deg; normal against the strike."""
    rng = np.random.default_rng(seed)
    P, D, n = (np.asarray(ws[k], float) for k in ("strike_points_m", "strike_dirs", "hanging_axis"))
    n_fam = -(-n_targets // starts)
    fam = rng.choice(len(P), n_fam, replace=n_fam > len(P))
    k = np.repeat(fam, starts)[:n_targets]
    p = P[k] + rng.normal(0, jitter_m, (n_targets, 3))
    turn = rng.uniform(-arc_deg / 2, arc_deg / 2, n_targets)
    p, normal = BR.rotate(p, turn, n), BR.rotate(-D[k], turn, n)
    df = pd.DataFrame(np.c_[p, normal], columns=["x", "y", "z", "nx", "ny", "nz"])
    df.insert(0, "bearing_deg", BR.bearing_deg(p, n))
    df.insert(0, "strike_point", k)
    df.insert(0, "family", np.repeat(np.arange(n_fam), starts)[:n_targets])
    df.insert(0, "target_id", [target_id(q) for q in p])
    return df

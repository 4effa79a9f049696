"""Figs. 2 and 3 render from the fits' artifacts, also in the degenerate cases of tiny budgets."""

import numpy as np

from embodied_snap.characterize import attachment, delay, release, snap
from embodied_snap.figures.limits import plot_limits
from embodied_snap.figures.snap import plot_snap


def fits(one_class=False):
    rng = np.random.default_rng(0)
    rel = [dict(category=c, v_peak=v, rate_peak=[8.0, 10.0, 7.0])
           for c, v in [("direct", 0.7), ("direct", 0.74), ("ramped", 1.2), ("instantaneous", 1.6)]]
    att = [dict(v_peak=v, tilt_deg=t, lateral_m=0.1, session=f"s{i % 3}", attached=bool(v > 1.2))
           for i, (v, t) in enumerate(zip(rng.uniform(0.8, 1.7, 24), rng.uniform(80, 120, 24)))]
    if one_class:
        for a in att:
            a["attached"] = False
    sn = [dict(rho1=a, rho2=b, session=f"s{i % 3}", v_peak=1.5 if one_class or a > 3000 else 0.8)
          for i, (a, b) in enumerate(zip(rng.uniform(2400, 3700, 30), rng.uniform(2100, 3300, 30)))]
    dl = [dict(tau=t, v_peak=1.0 + t, closest_m=0.14, attached=t >= 0.45) for t in (0.15, 0.3, 0.45, 0.5, 0.55)]
    for rows in (rel, att, sn, dl):  # each trial a group, as the fits' rows are
        for i, r in enumerate(rows):
            r["group_id"] = f"g{i:04d}"
    return (
        dict(ceiling_rad_s=[1.34, 2.2, 2.2]),
        release.summarize(rel, [1.34, 2.2, 2.2], 1.0),
        attachment.fit(att, 1.0),
        snap.fit(sn, 1.0, grid_n=21),
        delay.summarize(dl),
    )


def test_figures_render(tmp_path):
    for one_class in (False, True):
        sv, rel, att, sn, dl = fits(one_class)
        plot_limits(sv, rel, att, tmp_path / "f2.pdf", tmp_path / "f2.png", seed=1, attach_speed_mps=1.0)
        plot_snap(sn, dl, tmp_path / "f3.pdf", tmp_path / "f3.png", attach_speed_mps=1.0)
        for f in ("f2.pdf", "f2.png", "f3.pdf", "f3.png"):
            assert (tmp_path / f).stat().st_size > 1000

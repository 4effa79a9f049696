"""Fig. 7's drawing and moments (embodied_snap.figures.deployment): the arm as arcs through the
tracked frames, and the five moments of a trial in the order the paper shows them."""

import numpy as np
import pandas as pd
import pytest

from embodied_snap.figures import deployment as F

from paper_protocol import PROTO


def test_arc_is_a_circle_tangent_at_its_start_through_its_end():
    a, t, b = np.zeros(3), np.array([0.0, -1.0, 0.0]), np.array([0.3, -0.3, 0.0])  # a quarter circle
    pts, t_end = F.arc(a, t, b)
    np.testing.assert_allclose(pts[0], a, atol=1e-12)
    np.testing.assert_allclose(pts[-1], b, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pts - [0.3, 0.0, 0.0], axis=1), 0.3, atol=1e-12)
    np.testing.assert_allclose(t_end, [1.0, 0.0, 0.0], atol=1e-12)
    first = (pts[1] - pts[0]) / np.linalg.norm(pts[1] - pts[0])
    assert first @ t == pytest.approx(1.0, abs=1e-2)  # its chord is half a step off the tangent
    straight, t2 = F.arc(a, t, np.array([0.0, -0.5, 0.0]))
    np.testing.assert_allclose(straight[:, 0], 0.0)
    np.testing.assert_allclose(t2, t)
    # sections chain: each leaves along the one before
    segs = F.arm_curve(np.array([[0, 0, 0], [0.1, -0.25, 0], [0.3, -0.35, 0], [0.4, -0.3, 0.0]]), t)
    for s, nxt in zip(segs[:-1], segs[1:]):
        d0, d1 = s[-1] - s[-2], nxt[1] - nxt[0]
        assert d0 @ d1 / np.linalg.norm(d0) / np.linalg.norm(d1) > 0.99


def _trial(t_carry=2.6):
    """The tip still until the S1 release at 1.8 s, then straight onto the block (closest at the
    seal, 2.3 s), then it bounces off faster than it came (the peak speed is after the reach)."""
    t = np.arange(0, 3.0, 1 / 240)
    x = np.clip((t - 1.8) / 0.5, 0, 1) * 0.5 - np.clip((t - 2.3) / 0.1, 0, 1) * 0.3
    cols = dict(t=t)
    for body, pos in (("base", (0.0, 0.0, 0.0)), ("s1", (0.0, -0.2, 0.0)), ("s2", (0.0, -0.4, 0.0)),
                      ("tip", None), ("target", (0.5, -0.6, 0.0))):
        p = np.stack([x, np.full_like(t, -0.6), 0 * t], 1) if pos is None else np.tile(pos, (len(t), 1))
        cols.update({f"{body}_{a}": p[:, k] for k, a in enumerate("xyz")})
        cols.update({f"{body}_q{a}": (np.ones_like(t) if a == "w" else 0 * t) for a in "wxyz"})
        cols[f"{body}_valid"] = True
    labels = dict(t_preload=0.25, t_slack=1.0, t_s2=1.5, t_s1=1.8, t_attach=2.3, t_carry=t_carry)
    return pd.DataFrame(cols), dict(group_id="dep_0001", labels=labels)


def test_moments_are_in_the_papers_order():
    mc, meta = _trial()
    m = F.moments(mc, meta, 0.0, PROTO.sampling.max_gap_s)
    assert list(m) == list(F.MOMENTS)
    assert m["hanging"] == 0.125 and m["preload"] == 1.0
    assert m["snap"] == pytest.approx(2.05, abs=0.01)  # halfway from the release to the block
    assert m["reach"] == pytest.approx(2.3, abs=0.005) and m["attachment"] == 2.6
    with pytest.raises(ValueError, match="dep_0001: moments out of order"):
        F.moments(*_trial(t_carry=2.2), 0.0, PROTO.sampling.max_gap_s)

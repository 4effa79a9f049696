"""The acquisition protocol has one home (embodied_snap.acquisition): the simulated rig only
executes its programs. Its smoke recordings are byte-identical to those the rig made before the
protocol left embodied_snap/twin/ (tests/data/acquisition/smoke_sha256.json, written by that code).
A change that means to move the recordings (a new program, a longer group) rewrites the file in the
same commit and says why."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from embodied_snap.acquisition import draws as D
from embodied_snap.acquisition import programs as P
from embodied_snap.plan import twin_plan
from embodied_snap.reference import paper_values
from embodied_snap.twin.acquire import acquire_groups

from paper_protocol import HOLD, PROTO

REPO = Path(__file__).resolve().parent.parent
CONFIG = yaml.safe_load((REPO / "config.yaml").read_text())
BEFORE = REPO / "tests" / "data" / "acquisition" / "smoke_sha256.json"


def smoke_groups():
    return twin_plan(CONFIG["budgets"]["smoke"]["groups"], CONFIG["sessions"])


def sha256s(raw: Path, under: str = "groups") -> dict[str, str]:
    return {str(p.relative_to(raw)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((raw / under).rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_smoke_acquisition_is_byte_identical_to_the_rig_before_the_move(smoke_run):
    """Every group the workflow's acquisition jobs recorded in the session's smoke run (conftest),
    byte for byte as the rig before the move wrote it."""
    got, want = sha256s(smoke_run / "raw_data"), json.loads(BEFORE.read_text())
    assert sorted(got) == sorted(want)
    assert {k for k in want if got[k] != want[k]} == set()


def test_a_dynamics_group_gives_the_paper_s_windows_per_group(tmp_path):
    """A dynamics group is recorded long enough for windows.per_dynamics_group windows (paper
    IV-A: 11,284 sealed windows from 20 groups): resampled and cut into windows as the dynamics
    stage does, a smoke group gives that many to within one grid frame."""
    from embodied_snap.resample import resample_group
    from embodied_snap.windows import make_windows

    row = next(r for r in smoke_groups().to_dict("records") if r["category"] == "sealed")
    acquire_groups(pd.DataFrame([row]), tmp_path, seed=CONFIG["seed"], proto=PROTO, dt=CONFIG["twin"]["dt"],
                   hold=HOLD, progress=False)
    # recorded in process, alone, it is the group the rig before the move wrote, byte for byte
    want = json.loads(BEFORE.read_text())
    assert sha256s(tmp_path) == {k: v for k, v in want.items() if k.startswith(f"groups/{row['group_id']}/")}
    frames = resample_group(tmp_path, row["group_id"], PROTO.sampling.hz, PROTO.sampling.max_gap_s)
    n = len(make_windows(frames.assign(group_id=row["group_id"]), PROTO.windows)["anchors"])
    assert abs(n - PROTO.windows.per_dynamics_group) <= 1, n
    # the config's count is the paper's sealed windows over the paper budget's sealed groups
    paper = paper_values()["dynamics"]["sealed_n_windows"]["paper"]
    sealed = CONFIG["budgets"]["paper"]["groups"]["dynamics"]["sealed"]
    assert CONFIG["windows"]["per_dynamics_group"] == round(paper / sealed)


def test_a_groups_draws_do_not_depend_on_its_neighbours():
    g = smoke_groups().to_dict("records")
    one = D.draw_group(g[5], 7, PROTO, 0.01)
    again = D.draw_group(g[5], 7, PROTO, 0.01)
    other = D.draw_group(g[5], 8, PROTO, 0.01)
    assert one[1] == again[1] and one[1] != other[1]
    np.testing.assert_array_equal(one[3], again[3])


def test_every_set_gets_the_draws_its_trials_need():
    for row in smoke_groups().to_dict("records"):
        _, prog, off, goals, times, cue = D.draw_group(row, 1, PROTO, 0.01)
        assert goals.shape[1] == 9 and np.isfinite(goals).all()
        assert (off is not None) == D.has_target(row)
        assert (cue is not None) == (row["evidence_set"] == "held_base")
        if cue is not None:
            assert times["t_preload"] + 0.5 <= cue <= times["t_s1"] + 0.6
        assert prog["kind"] in ("burst", "direct", "primitive", "ramped", "instantaneous")


def test_the_goal_trace_is_the_programs_at_any_step():
    prog = dict(P.OPERATING, kind="instantaneous", bearing=PROTO.primitive.phi0_deg)
    fine, t1 = P.goals_of(prog, 0.001, PROTO)
    coarse, t2 = P.goals_of(prog, 0.01, PROTO)
    assert t1 == t2
    n = min(len(coarse), len(fine[::10]))
    np.testing.assert_allclose(coarse[:n], fine[::10][:n], atol=1e-6)  # a function of t, sampled

"""bench/timeline.py counts cores, not jobs: a job takes as many lanes (and cores) as its threads, so
the two-thread joint GRU training is no idle core."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from timeline import lanes, occupancy  # noqa: E402


def test_a_job_takes_as_many_cores_as_its_threads():
    js = [dict(start=0.0, end=10.0, threads=2), dict(start=10.0, end=15.0, threads=1),
          dict(start=12.0, end=14.0, threads=1)]
    occ = occupancy(js)
    assert (occ[2], occ[1]) == (12.0, 3.0)
    assert lanes(js, 2) == [[0, 1], [0], [1]]

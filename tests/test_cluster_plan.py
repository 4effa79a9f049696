"""bench/cluster_plan.py on DAGs whose critical path and schedule are known by hand."""

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench"))

import cluster_plan as C  # noqa: E402


def job(rule, inp, out, s, threads=1, priority=0):
    return dict(rule=rule, wildcards="", input=inp, output=out, threads=threads, priority=priority,
                benchmark=None, start=0.0, end=float(s))


# a (10 s) -> b (20 s) and c (5 s, 2 threads) -> d (1 s); c reads a file inside a's output folder.
DIAMOND = [job("a", [], ["out/a"], 10), job("b", ["out/a"], ["b.txt"], 20),
           job("c", ["out/a/x.txt"], ["c.txt"], 5, threads=2), job("d", ["b.txt", "c.txt", "src.py"], ["d.txt"], 1)]


def units(js, groups=None, root=REPO):
    deps = C.dependencies(js, C.producers(js, root))
    return C.cluster_jobs(js, C.durations(js, root), deps, groups or {})


def test_dependencies_through_files_and_folders():
    assert C.dependencies(DIAMOND, C.producers(DIAMOND, REPO)) == [set(), {0}, {0}, {1, 2}]


def test_critical_path_and_plans_known_answer():
    u = units(DIAMOND)
    assert C.critical_path(u) == (31.0, [0, 1, 3])
    assert C.critical_path(u, overhead=2.0)[0] == 37.0
    assert C.plan(u, nodes=8, node_cores=2) == 31.0  # unlimited: the critical path
    # one node of two cores: b and c cannot run side by side (c needs both cores): 10 + 5 + 20 + 1
    assert C.plan(u, nodes=1, node_cores=2) == 36.0
    assert C.plan(u, nodes=1, node_cores=4) == 31.0
    assert C.plan(u, nodes=2, node_cores=2) == 31.0


def test_a_group_is_one_cluster_job_that_waits_for_all_it_reads():
    u = units(DIAMOND, {"b": "g", "d": "g"})
    assert len(u) == 3 and sorted(x["s"] for x in u) == [5.0, 10.0, 21.0]
    # b + d is submitted once c is done too: 10 + 5 + 21
    assert C.critical_path(u)[0] == 36.0


def test_priority_goes_first_on_a_full_node():
    """Two cores; y (1 s) feeds z (10 s), both with priority: y beside x, then z, then w (20 s).
    Without priorities, in run order: x and w, then y and z (21 s)."""
    js = [job("x", [], ["x"], 10), job("w", [], ["w"], 10), job("y", [], ["y"], 1, priority=1),
          job("z", ["y"], ["z"], 10, priority=1)]
    assert C.plan(units(js), nodes=1, node_cores=2) == 20.0
    assert C.plan(units([dict(j, priority=0) for j in js]), nodes=1, node_cores=2) == 21.0


def test_a_recording_waits_for_the_checkpoint_that_wrote_it(tmp_path):
    (tmp_path / "results/twin/acquired").mkdir(parents=True)
    (tmp_path / "results/twin/acquired/s1.json").write_text('{"groups": [{"group_id": "g7"}]}')
    js = [job("twin_acquire", [], ["results/twin/acquired/s1.json"], 3),
          job("twin_acquire", [], ["results/twin/acquired/s2.json"], 4),
          job("validate_shard", ["raw_data/groups/g7/mocap.parquet", "raw_data/groups/g8/meta.json"], ["v"], 1)]
    assert C.dependencies(js, C.producers(js, tmp_path))[2] == {0}

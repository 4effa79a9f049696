"""Fixtures shared by several test modules. Helper modules (fakerig, lineage_tree) write files;
what is built in memory lives here."""

import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from embodied_snap.resample import COMMAND_COLUMNS, STATE_COLUMNS

# The suite's deployment trials run at normal priority, as before the real-time loop: its priority
# step is unit-tested with fakes (test_loop.py) and measured under load by bench/loop_load.py.
os.environ.setdefault("ESNAP_REALTIME", "0")


def pytest_collection_modifyitems(config, items):
    """`make test` runs on two workers, a module per worker at a time (`--dist loadfile`), in this
    order (`--no-loadscope-reorder`): one module that reads the session's smoke run (smoke_run
    below) first, so its build starts at once; then the modules that do not read it, the slow ones
    first, while it builds; then the other modules that read it, on whichever worker is free."""
    # fixturenames is the whole closure: a module fixture that reads smoke_run counts too
    smoke = {item.module.__name__ for item in items if "smoke_run" in item.fixturenames}
    slow = {item.module.__name__ for item in items if item.get_closest_marker("slow")}
    first = min(smoke, default=None)

    def rank(item):
        name = item.module.__name__
        if name == first:
            return 0
        if name in smoke:
            return 3
        return 1 if name in slow else 2

    items.sort(key=rank)  # stable: each module's own order is kept


def _synthetic_frames(n_groups=6, n=140, seed=0):
    """Servos lag their step goals (first order); bodies and axis follow the servo positions
    through a fixed linear map with a little sway: learnable, but not constant velocity."""
    rng = np.random.default_rng(seed)
    A = rng.normal(0, 2e-5, (9, 12))
    out = []
    for g in range(n_groups):
        goal = np.repeat(rng.uniform(0, 3000, (n // 20 + 1, 9)), 20, 0)[:n]
        pos = np.zeros((n, 9))
        for k in range(1, n):
            pos[k] = pos[k - 1] + 0.3 * (goal[k - 1] - pos[k - 1])
        body = pos @ A + 0.01 * np.sin(np.arange(n) / 5)[:, None] + np.tile([0.0, -0.5, 0.0], 4)  # hangs along -y
        f = pd.DataFrame(np.c_[body, pos, goal], columns=STATE_COLUMNS + COMMAND_COLUMNS).astype(np.float32)
        f.insert(0, "t", np.arange(n) * 0.02)
        f.insert(0, "group_id", f"g{g}")
        out.append(f)
    return pd.concat(out, ignore_index=True)


@pytest.fixture(scope="session")
def synthetic_frames():
    """A function (n_groups, n, seed) -> 50 Hz frames of a learnable toy arm."""
    return _synthetic_frames


@pytest.fixture(scope="session")
def smoke_build(tmp_path_factory, worker_id):
    """The session's one smoke-budget run of the whole DAG (`snakemake all robustness sensitivity
    landscape`) in a copy of the repository: built once for all workers (the first to ask builds it
    under a file lock, the others wait), and never changed after (smoke_run hands out copies).
    ESNAP_SMOKE_RUN=DIR starts from a finished run's recordings, results and records, which Snakemake
    then brings up to date with this code (the edit loop)."""
    from filelock import FileLock

    from test_workflow import COPY, REPO, snakemake

    base = tmp_path_factory.getbasetemp()
    shared = base if worker_id == "master" else base.parent  # every worker's folder is under one
    d, built, failed = shared / "smoke_build", shared / "smoke_build.done", shared / "smoke_build.failed"
    with FileLock(str(shared / "smoke_build.lock")):
        if failed.exists():
            pytest.fail(f"the session's smoke run failed on another worker:\n{failed.read_text()}")
        if built.exists():
            return d
        d.mkdir()
        done = os.environ.get("ESNAP_SMOKE_RUN")
        for name in ("raw_data", "results", ".snakemake", ".budgets", "logs", "benchmarks") if done else ():
            if (Path(done) / name).exists():
                shutil.copytree(Path(done) / name, d / name, symlinks=True)
        for name in COPY:
            src = REPO / name
            (shutil.copytree if src.is_dir() else shutil.copy2)(
                src, d / name, **({"ignore": shutil.ignore_patterns("__pycache__")} if src.is_dir() else {})
            )
        try:
            snakemake(d, "all", "robustness", "sensitivity", "landscape")
            # The crate comes after every product; the later targets' products made in the same run
            # may finish after it, and the next `snakemake all` rewrites it to list them.
            snakemake(d, "all")
        except BaseException as e:
            failed.write_text(str(e)[-6000:])
            raise
        built.touch()
        return d


@pytest.fixture(scope="module")
def smoke_run(smoke_build, tmp_path_factory):
    """A module's own copy of the session's smoke run (smoke_build): what one module changes in it,
    another never sees. The copy keeps times (copy2), so Snakemake finds nothing to do in it."""
    d = tmp_path_factory.mktemp("wf") / "run"
    shutil.copytree(smoke_build, d, symlinks=True)
    return d


@pytest.fixture
def no_port(monkeypatch):
    """Opening a port, through the client or dynamixel-sdk itself, fails the test (a module that
    refuses arguments before any port opens uses it for every test: `pytestmark`)."""
    import dynamixel_sdk

    from embodied_snap.deploy import client

    def opened(*args, **kwargs):
        pytest.fail("a port was opened")

    monkeypatch.setattr(client, "Bus", opened)
    monkeypatch.setattr(dynamixel_sdk.PortHandler, "openPort", opened)

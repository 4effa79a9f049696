"""Fixtures shared by several test modules. Helper modules (fakerig, lineage_tree) write files;
what is built in memory lives here."""

import os
import shutil

import numpy as np
import pandas as pd
import pytest

from embodied_snap.resample import COMMAND_COLUMNS, STATE_COLUMNS

# The suite's deployment trials run at normal priority, as before the real-time loop: its priority
# step is unit-tested with fakes (test_loop.py) and measured under load by bench/loop_load.py.
os.environ.setdefault("ESNAP_REALTIME", "0")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """`make test` runs on two workers (pytest-xdist, `--dist loadgroup`): a module's tests share a
    worker, so its module fixtures are built once, and so do all the tests that read the session's
    smoke run (conftest.smoke_run), whatever their module, so the run is built once."""
    for item in items:
        group = "smoke_run" if "smoke_run" in item.fixturenames else item.module.__name__
        item.add_marker(pytest.mark.xdist_group(group))


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
def smoke_run(tmp_path_factory):
    """One smoke-budget run of the whole DAG (`snakemake all robustness sensitivity landscape`) in a copy of
    the repository, shared
    by every test module that needs a finished run (test_workflow, test_report): a second run would
    cost minutes. Modules that change files in it restore them."""
    from test_workflow import COPY, REPO, snakemake

    d = tmp_path_factory.mktemp("wf")
    for name in COPY:
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(
            src, d / name, **({"ignore": shutil.ignore_patterns("__pycache__")} if src.is_dir() else {})
        )
    snakemake(d, "all", "robustness", "sensitivity", "landscape")
    # The crate comes after every product; the later targets' products made in the same run may finish
    # after it, and the next `snakemake all` rewrites it to list them (the Snakefile's `crate`).
    snakemake(d, "all")
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

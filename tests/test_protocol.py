"""One protocol from the validated config (issue 10): values, immutability, the Snakemake params
round trip, and the grid: the protocol's one rate, which a config cannot set (refused in one line)."""

import copy
import dataclasses
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from embodied_snap import protocol

from paper_protocol import PROTO

REPO = Path(__file__).resolve().parent.parent
CONFIG = yaml.safe_load((REPO / "config.yaml").read_text())


def test_values_come_from_config():
    assert PROTO.sampling.dt == 0.02  # exactly the step the pipeline always used
    assert (PROTO.windows.history, PROTO.windows.lookahead, PROTO.windows.horizon) == (20, 5, 25)
    assert PROTO.primitive.phi0_deg == 210.0 and PROTO.primitive.s2_ramp_s == 0.13
    assert PROTO.primitive.timing_s == (0.45, 0.675)
    assert PROTO.rig.rated_speed_tick_s == 3140.0 and PROTO.thresholds.attach_speed_mps == 1.0
    assert PROTO.rig.arm_length_m * 1e3 == 730.0  # the millimetres the tip errors were always divided by
    cfg = copy.deepcopy(CONFIG)
    cfg["resample"]["max_gap_s"], cfg["policy"]["ranges"]["tau"] = 0.2, [0.5, 0.6]
    cfg["rig"]["rated_speed_tick_s"] = 3000
    p = protocol.load(cfg)
    assert (p.sampling.max_gap_s, p.primitive.timing_s, p.rig.rated_speed_tick_s) == (0.2, (0.5, 0.6), 3000.0)
    assert p.sampling.dt == 0.02  # the grid is the protocol's, whatever the config


def test_frozen_and_params_round_trip():
    with pytest.raises(dataclasses.FrozenInstanceError):
        PROTO.sampling.hz = 25
    p = protocol.params(CONFIG, "sampling", "primitive")
    assert yaml.safe_load(yaml.safe_dump(p)) == p  # plain values: a Snakemake param
    q = protocol.from_params(p)
    assert q.sampling == PROTO.sampling and q.primitive == PROTO.primitive and q.rig is None
    with pytest.raises(TypeError):
        q.primitive.ranges["tau"] = (0.1, 0.2)
    with pytest.raises(KeyError):
        protocol.params(CONFIG, "nonsense")


def test_the_grid_is_the_protocols_and_a_config_cannot_set_it():
    from embodied_snap import runconfig

    # the `sampling` param as config.yaml's `hz: 50` gave it (an int: the same param, the same bytes)
    assert protocol.GRID_HZ == 50 and type(protocol.GRID_HZ) is int
    assert protocol.params(CONFIG, "sampling") == {"sampling": {"hz": 50, "max_gap_s": 0.1}}
    assert "hz" not in CONFIG["resample"]
    cfg = copy.deepcopy(CONFIG)
    cfg["resample"]["hz"] = 25
    with pytest.raises(runconfig.ConfigError) as e:
        runconfig.validate(cfg)
    line = str(e.value)
    assert "\n" not in line and "resample" in line and "'hz' was unexpected" in line, line


@pytest.mark.slow
def test_a_config_that_sets_the_grid_stops_the_workflow_at_start_up(tmp_path):
    for name in ("Snakefile", "config.yaml", "rules", "workflow_scripts", "schemas", "envs", "profiles",
                 "reference", "report", "embodied_snap"):
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, tmp_path / name)
    (tmp_path / "hz25.yaml").write_text("resample:\n  hz: 25\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}"}
    r = subprocess.run(["snakemake", "-n", "--cores", "1", "--config", "budget=smoke", "--configfile", "hz25.yaml"],
                       cwd=tmp_path, env=env, capture_output=True, text=True)
    out = r.stdout + r.stderr
    assert r.returncode != 0
    lines = [ln for ln in out.splitlines() if "'hz' was unexpected" in ln]
    assert len(lines) == 1 and re.search(r"config: resample\b", lines[0]), out[-2000:]
    assert not (tmp_path / "results").exists() and not (tmp_path / "raw_data").exists()


def test_paper_values_only_feed_the_paper_column():
    """reference/paper_values.yaml is an input of the claims tables, the claims ledger (which judges
    ours against the paper column) and the twin's report alone, and
    only embodied_snap/reference.py reads it: no result is computed from a paper value."""
    readers = set()
    for smk in (REPO / "rules").glob("*.smk"):
        # rules may sit indented under `if TWIN:` and the like
        for block in re.split(r"\n(?=[ \t]*(?:rule|checkpoint) )", smk.read_text()):
            m = re.match(r"\s*(?:rule|checkpoint) (\w+):", block)
            if m and "reference/paper_values.yaml" in block:
                readers.add(m.group(1))
    assert readers == {"table_characterize_claims", "table_dynamics_claims", "table_policy_claims",
                       "table_ablation_claims", "table_robustness_claims", "twin_validation", "deploy_table",
                       "table_claims"}
    code = [p for d in ("embodied_snap", "workflow_scripts") for p in (REPO / d).rglob("*.py")]
    reads = re.compile(r"\bpaper_values\s*\(|import [^\n]*\bpaper_values\b")  # a call or an import
    users = {p.relative_to(REPO).as_posix() for p in code if reads.search(p.read_text())}
    assert users == {"embodied_snap/reference.py"}

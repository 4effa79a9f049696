"""Budgets on one checkout (embodied_snap/budget.py): a switch parks one budget's trees and brings
another's back, nothing is deleted or mixed, and a command asking for a budget the trees do not
hold stops with one line naming both budgets and the command that fits."""

from __future__ import annotations

import hashlib
import json
import shutil
import sys
from pathlib import Path

import pytest
import yaml

from embodied_snap import budget
from embodied_snap.plan import twin_plan

from test_workflow import run

REPO = Path(__file__).resolve().parent.parent
CFG = yaml.safe_load((REPO / "config.yaml").read_text())


def cfg(name="paper", **raw):
    return {**CFG, "budget": name, "raw_data": {**CFG["raw_data"], **raw}}


def fill(root: Path, name: str) -> dict[str, str]:
    """A run's trees as a twin run of `name` leaves them: index.csv of that plan, a result, a record."""
    ids = twin_plan(CFG["budgets"][name]["groups"], CFG["sessions"]).group_id
    files = {
        "raw_data/index.csv": "group_id\n" + "\n".join(ids) + "\n",
        "raw_data/sealed.json": json.dumps({"budget": name}),
        f"results/figures/fig_{name}.txt": name,
        "logs/x.log": name,
        ".snakemake/metadata/abc": name,
    }
    for p, text in files.items():
        (root / p).parent.mkdir(parents=True, exist_ok=True)
        (root / p).write_text(text)
    return files


def contents(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): p.read_text() for p in sorted(root.rglob("*"))
            if p.is_file() and not str(p.relative_to(root)).startswith(".budgets")}


def test_an_empty_place_is_claimed_by_the_first_run(tmp_path):
    assert budget.active(cfg(), tmp_path) is None
    assert budget.claim(cfg("smoke"), tmp_path) == "smoke"
    assert json.loads((tmp_path / budget.ACTIVE).read_text()) == {"budget": "smoke"}
    # still empty: another budget may claim it (a dry run of one leaves nothing to protect)
    assert budget.claim(cfg("paper"), tmp_path) == "paper"


def test_asking_for_another_budget_is_one_line_naming_both_and_the_commands(tmp_path):
    fill(tmp_path, "smoke")
    budget.claim(cfg("smoke"), tmp_path)
    with pytest.raises(budget.BudgetError) as e:
        budget.claim(cfg("paper"), tmp_path, argv=["/x/bin/snakemake", "--report", "results/report.html"])
    msg = str(e.value)
    assert "\n" not in msg
    assert "hold the smoke budget's run and this asks for paper" in msg
    assert "`esnap budget paper`" in msg
    assert "`snakemake --report results/report.html --config budget=smoke`" in msg


def test_trees_with_no_record_are_the_budget_their_index_lists(tmp_path):
    fill(tmp_path, "quick")
    assert budget.active(cfg(), tmp_path) == "quick"
    with pytest.raises(budget.BudgetError, match="hold the quick budget's run"):
        budget.claim(cfg("smoke"), tmp_path)


def test_a_switch_parks_and_restores_byte_for_byte(tmp_path):
    smoke = fill(tmp_path, "smoke")
    budget.claim(cfg("smoke"), tmp_path)
    assert "now hold the quick budget (empty" in budget.switch(cfg(), "quick", tmp_path)
    assert contents(tmp_path) == {}  # nothing of smoke's left in place, nothing deleted:
    assert (tmp_path / ".budgets/smoke/raw_data/sealed.json").exists()
    quick = fill(tmp_path, "quick")
    assert "back" in budget.switch(cfg(), "smoke", tmp_path)
    assert contents(tmp_path) == smoke
    budget.switch(cfg(), "quick", tmp_path)
    assert contents(tmp_path) == quick
    assert budget.switch(cfg(), "quick", tmp_path).endswith("already hold the quick budget's run")
    assert not (tmp_path / ".budgets/quick").exists()  # restored whole, no empty folders left


def test_a_real_rigs_recordings_stay_where_they_are(tmp_path):
    fill(tmp_path, "smoke")
    rig = cfg(source="rig")
    budget.claim({**rig, "budget": "smoke"}, tmp_path)
    budget.switch(rig, "paper", tmp_path)
    assert (tmp_path / "raw_data/index.csv").exists() and not (tmp_path / "results").exists()


def test_a_switch_refuses_what_would_lose_or_mix_files(tmp_path):
    with pytest.raises(budget.BudgetError, match="not one of paper, quick, smoke"):
        budget.switch(cfg(), "nonsense", tmp_path)
    fill(tmp_path, "smoke")
    budget.claim(cfg("smoke"), tmp_path)
    (tmp_path / ".snakemake/locks").mkdir(parents=True)
    (tmp_path / ".snakemake/locks/0.input.lock").write_text("")
    with pytest.raises(budget.BudgetError, match="a Snakemake run holds this directory"):
        budget.switch(cfg(), "paper", tmp_path)
    shutil.rmtree(tmp_path / ".snakemake/locks")
    (tmp_path / ".budgets/smoke/results").mkdir(parents=True)
    with pytest.raises(budget.BudgetError, match="parked trees would be overwritten"):
        budget.switch(cfg(), "paper", tmp_path)
    assert (tmp_path / "results/figures/fig_smoke.txt").exists()  # refused before anything moved


def test_validate_names_the_budget_a_tree_was_recorded_for(tmp_path):
    fill(tmp_path, "smoke")
    with pytest.raises(budget.BudgetError) as e:
        budget.check_tree(cfg(), tmp_path / "raw_data", argv=["esnap", "validate", "raw_data"])
    assert str(e.value).endswith("holds the smoke budget's recordings and this asks for paper: "
                                 "`esnap validate raw_data --config budget=smoke`")
    budget.check_tree(cfg("smoke"), tmp_path / "raw_data")
    (tmp_path / "raw_data/index.csv").write_text("group_id\nlab_0001\n")  # a lab's tree: no budget's
    budget.check_tree(cfg(), tmp_path / "raw_data")


def test_with_budget_keeps_every_other_argument():
    w = budget.with_budget
    assert w(["snakemake", "-n"], "smoke") == "snakemake -n --config budget=smoke"
    assert w(["snakemake", "--config", "budget=paper", "seed=3", "-n"], "smoke") == \
        "snakemake --config seed=3 budget=smoke -n"


# --- the README's sequence, for real, in a copy of the repository ------------------------------------

COPY = ["Snakefile", "config.yaml", "rules", "workflow_scripts", "schemas", "envs", "profiles",
        "reference", "report", "embodied_snap", "docs", "Makefile", "pyproject.toml", "requirements.lock"]
BIN = Path(sys.executable).parent
# A reduced quick budget: the switch is the same whatever the sizes; minutes saved.
REDUCED = {"budgets": {"quick": CFG["budgets"]["smoke"] | {"split": {"validation": 2}}}}


# Snakemake's own notice before it reads the Snakefile (profiles/default), not the workflow's
SNAKEMAKES_OWN = "Using workflow specific profile"


def sh(cwd, *cmd):
    return run(list(cmd), cwd, check=False)


def digest(root: Path, tree: str) -> str:
    h = hashlib.sha256()
    for p in sorted((root / tree).rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(root)).encode() + p.read_bytes())
    return h.hexdigest()


@pytest.mark.slow
def test_switching_budgets_needs_no_delete_and_rebuilds_nothing(tmp_path, smoke_run):
    # The session's smoke run (conftest.smoke_run) is the smoke budget's tree: nothing of it to rebuild.
    shutil.copytree(smoke_run, tmp_path, symlinks=True, dirs_exist_ok=True)
    for name in COPY:
        src = REPO / name
        if not (tmp_path / name).exists():
            (shutil.copytree if src.is_dir() else shutil.copy2)(src, tmp_path / name)
    (tmp_path / "reduced.yaml").write_text(yaml.safe_dump(REDUCED))
    part = ["results/raw/manifest.json", "raw_data/sealed.json"]  # recordings, the sealed record, results
    assert sh(tmp_path, "snakemake", "--cores", "2", *part, "--config", "budget=smoke").returncode == 0
    smoke = {t: digest(tmp_path, t) for t in ("raw_data", "results")}

    # Every bare command now asks for config.yaml's budget (paper): one line, naming both and the fix.
    for cmd in (["snakemake", "-n"], ["snakemake", "--lint"], ["snakemake", "--report", "results/report.html"],
                ["esnap", "validate", "raw_data"]):
        r = sh(tmp_path, *cmd)
        lines = [x for x in r.stderr.strip().splitlines() if not x.startswith(SNAKEMAKES_OWN)]
        assert r.returncode in (1, 2) and len(lines) == 1, (cmd, r.stderr)
        assert "smoke budget's" in lines[0] and "--config budget=smoke" in lines[0], lines[0]

    # make paper BUDGET=quick switches by itself (its recipe, as make would run it)
    plan = sh(tmp_path, "make", "-n", "paper", "BUDGET=quick", f"VENV={BIN.parent}").stdout
    assert plan.index("esnap budget quick") < plan.index("snakemake --cores 2 all --config budget=quick")
    assert sh(tmp_path, "esnap", "budget", "quick").returncode == 0
    r = sh(tmp_path, "snakemake", "--cores", "2", *part, "--configfile", "reduced.yaml", "--config", "budget=quick")
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / ".budgets/smoke/raw_data/sealed.json").exists()

    # ... and back: smoke's trees as they were, byte for byte, and nothing to rebuild
    assert sh(tmp_path, "esnap", "budget", "smoke").returncode == 0
    assert {t: digest(tmp_path, t) for t in smoke} == smoke
    r = sh(tmp_path, "snakemake", "-n", "--cores", "2", *part, "--config", "budget=smoke")
    assert r.returncode == 0 and "Nothing to be done" in r.stdout + r.stderr, r.stdout[-3000:]
    assert (tmp_path / ".budgets/quick/raw_data/sealed.json").exists()


@pytest.mark.parametrize("text", [b"", b"\x00\xff\xfe binary", b"no,group_id,column\n1,2,3\n"])
def test_a_broken_index_is_no_budgets_and_left_to_the_gate(tmp_path, text):
    (tmp_path / "raw_data").mkdir()
    (tmp_path / "raw_data/index.csv").write_bytes(text)
    budget.check_tree(cfg(), tmp_path / "raw_data")
    assert budget.active(cfg(), tmp_path) is None


def test_an_index_linked_out_is_never_read(tmp_path):
    outside = tmp_path / "elsewhere.csv"
    outside.write_text("group_id\n" + "\n".join(twin_plan(CFG["budgets"]["smoke"]["groups"], CFG["sessions"]).group_id))
    (tmp_path / "raw_data").mkdir()
    (tmp_path / "raw_data/index.csv").symlink_to(outside)
    budget.check_tree(cfg(), tmp_path / "raw_data")  # a smoke index, but outside: not read, so no line

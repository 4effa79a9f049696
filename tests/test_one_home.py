"""One home per word: an architecture, or an evidence set's category, is added by editing its table
(embodied_snap/policy/architectures.py, embodied_snap/rawformat.py EVIDENCE) and config.yaml alone,
in a copy of the repository, and it reaches the DAG, the claims and Fig. 5's data / the plan.
Also: a name the tables do not hold is refused in one line, and results are written through one
module (embodied_snap.io), never through the recording format's."""

from __future__ import annotations

import ast
import json
import re
import shutil
import sys
from pathlib import Path

import pytest

from embodied_snap import runconfig
from embodied_snap.lineage.policy import POLICY
from embodied_snap.policy import architectures
from embodied_snap.rawformat import EVIDENCE

from test_workflow import COPY, REPO, dry_jobs, run

TESTS = Path(__file__).resolve().parent


def _copy(dst: Path) -> Path:
    for name in COPY:
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(
            src, dst / name, **({"ignore": shutil.ignore_patterns("__pycache__")} if src.is_dir() else {})
        )
    return dst


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    s = path.read_text()
    assert s.count(old) == count, (path, old)
    path.write_text(s.replace(old, new))


def _python(cwd: Path, code: str) -> dict:
    """`code` run in a fresh interpreter that imports the copy's package; it prints one JSON line."""
    code = (f"import sys; sys.path.insert(1, {str(TESTS)!r})\n"
            f"import embodied_snap; assert embodied_snap.__file__.startswith({str(cwd)!r}), embodied_snap.__file__\n"
            + code)
    return json.loads(run([sys.executable, "-c", code], cwd).stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------- a fifth architecture

ROW = '    Architecture("centralised32", [mlp_sizes(3, 32, 6)], "joint", "Centralised-32", 4),\n'


def add_architecture(d: Path) -> None:
    """One row in the table, one seed count per budget in config.yaml: nothing else."""
    unshared = '    Architecture("unshared"'
    _edit(d / "embodied_snap/policy/architectures.py", unshared, ROW + unshared)
    cfg = d / "config.yaml"
    s, n = re.subn(r"(centralised16: \d+)\}", r"\1, centralised32: 1}", cfg.read_text())
    assert n == 3  # the paper, quick and smoke budgets
    cfg.write_text(s)


SUMMARY = """
import numpy as np, pandas as pd
from test_policy_analysis import run, evals_for, TOLS, D_F, V_MIN, BUDGET, GENS
from embodied_snap.policy import analysis as A, networks
rng = np.random.default_rng(0)
runs, evals = [], []
for a, seeds in (("shared", 2), ("centralised", 2), ("unshared", 1), ("centralised32", 1)):
    for s in range(seeds):
        runs.append(run(a, s, [0.1 * (g + 1) + 0.01 * s for g in range(GENS)], n_params=networks.n_params(a)))
        evals.append(evals_for(a, s, 30 + s, rng))
summary = A.summarize(runs, pd.concat(evals, ignore_index=True), evals_for("fixed", -1, 20, rng), BUDGET,
                      A.SummaryCriteria(tolerances=TOLS, d_f=D_F, v_min=V_MIN, timing_s=(0.45, 0.675)))
"""

CLAIMS_AND_FIG5 = SUMMARY + """
import json
from embodied_snap.policy import claims
from embodied_snap.figures import style
figs = []
style.save = lambda fig, pdf, png: figs.append(fig)
from embodied_snap.figures.benchmark import plot_benchmark
plot_benchmark(summary, "fig5.pdf", "fig5.png")
a, b, c = figs[0].axes
from embodied_snap.sources import trace
ours, _ = trace(claims._ours, dict(summary=("summary.json", summary)))
print(json.dumps(dict(
    archs=summary["archs"],
    ours={k: v for k, v in ours.items() if "centralised32" in k},
    legend=[t.get_text() for t in b.get_legend().get_texts()],
    colours={ln.get_label(): ln.get_color() for ln in a.get_lines()},
    ticks=[t.get_text() for t in c.get_xticklabels()],
)))
"""


@pytest.fixture(scope="module")
def fifth(tmp_path_factory):
    d = _copy(tmp_path_factory.mktemp("fifth"))
    add_architecture(d)
    return d


def test_a_fifth_architecture_is_searched(fifth):
    jobs = dry_jobs(fifth)
    assert ("policy_search", "arch=centralised32, seed=0") in jobs
    assert ("policy_evaluate", "arch=centralised32, seed=0") in jobs


def test_a_fifth_architecture_reaches_the_claims_and_fig5(fifth):
    got = _python(fifth, CLAIMS_AND_FIG5)
    assert got["archs"] == ["shared", "centralised", "centralised32", "unshared"]  # the table's order
    assert got["ours"]["n_params_centralised32"] == 3 * 32 + 32 + 32 * 32 + 32 + 6 * 32 + 6
    assert got["ours"]["seeds_centralised32"] == 1
    assert got["ours"]["reward_centralised32_mean"] is not None
    assert {"reach_centralised32_n", "attach_5cm_centralised32_mean"} <= set(got["ours"])
    assert "Centralised-32 (1382), n=1" in got["legend"]  # its label, in (a) and the shared legend
    assert got["colours"]["Centralised-32 (1382), n=1"] == "#E69F00"  # its colour: PALETTE[4]
    assert "Central.-32" in got["ticks"]  # panel (c)


@pytest.mark.slow
def test_without_its_row_the_architecture_is_refused_in_one_line(tmp_path):
    d = _copy(tmp_path)
    add_architecture(d)
    _edit(d / "embodied_snap/policy/architectures.py", ROW, "")
    r = run(["snakemake", "-n", "--cores", "1", "--config", "budget=smoke"], d, check=False)
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if "centralised32" in ln]
    assert r.returncode != 0 and lines == [
        "error: config: budgets.paper.policy.seeds: 'centralised32' is not an architecture (known: shared, "
        "centralised, centralised16, unshared; embodied_snap/policy/architectures.py)"], r.stderr[-2000:]


def test_unknown_or_missing_names_are_refused(tmp_path):
    cfg = runconfig.load(root=REPO)
    assert runconfig.names_error(cfg) is None
    seeds = cfg["budgets"]["smoke"]["policy"]["seeds"]
    seeds["centralised64"] = 1
    assert runconfig.names_error(cfg).startswith(
        "config: budgets.smoke.policy.seeds: 'centralised64' is not an architecture")
    del seeds["centralised64"], seeds["unshared"]
    assert runconfig.names_error(cfg) == ("config: budgets.smoke.policy.seeds: 'unshared' is a required property "
                                          "(an architecture of embodied_snap/policy/architectures.py)")
    cfg = runconfig.load(root=REPO)
    cfg["budgets"]["quick"]["groups"]["dynamics"]["extra"] = 1
    assert runconfig.names_error(cfg).startswith("config: budgets.quick.groups.dynamics: 'extra' is not a category")
    cfg = runconfig.load(root=REPO)
    cfg["budgets"]["quick"]["groups"]["deployment"] = {"placement": 1}  # recorded by the deployment stage
    assert runconfig.names_error(cfg).startswith("config: budgets.quick.groups: 'deployment' is not an evidence set")
    (tmp_path / "extra.yaml").write_text("budgets: {smoke: {groups: {dynamics: {extra: 1}}}}\n")
    with pytest.raises(runconfig.ConfigError, match="'extra' is not a category"):  # as `esnap` loads it
        runconfig.load(tmp_path / "extra.yaml", root=REPO)


BAD_PATTERN = ("config: raw_data.group_id_pattern: '(dyn' is not a regular expression (missing ), "
               "unterminated subpattern at position 0) (rule: group ids match a Python regular expression)")


@pytest.mark.slow
def test_a_group_id_pattern_that_is_no_regular_expression_is_one_line(tmp_path):
    """raw_data.group_id_pattern is compiled with the config, before the plan, index.csv or an
    import matches an id against it: a broken one is one line naming the key, for `esnap` (every
    command loads its config through runconfig) and for the workflow, not the regex engine's
    traceback."""
    cfg = runconfig.load(root=REPO)
    assert runconfig.pattern_error(cfg) is None
    cfg["raw_data"]["group_id_pattern"] = "(dyn"
    assert runconfig.beyond_schema_error(cfg) == BAD_PATTERN
    (tmp_path / "bad.yaml").write_text("raw_data: {group_id_pattern: '(dyn'}\n")
    with pytest.raises(runconfig.ConfigError) as e:
        runconfig.load(tmp_path / "bad.yaml", root=REPO)
    assert str(e.value) == BAD_PATTERN
    d = tmp_path / "wf"
    d.mkdir()
    _copy(d)
    (d / "bad.yaml").write_text("raw_data: {group_id_pattern: '(dyn'}\n")
    r = run(["snakemake", "-n", "--cores", "1", "--config", "budget=smoke", "--configfile", "bad.yaml"], d,
            check=False)
    assert r.returncode != 0 and [ln for ln in (r.stdout + r.stderr).splitlines() if "(dyn" in ln] == [
        f"error: {BAD_PATTERN}"], r.stderr[-2000:]


def test_the_table_is_every_architecture():
    assert architectures.NAMES == ("shared", "centralised", "centralised16", "unshared")
    assert {a.sharing for a in architectures.TABLE} <= set(architectures.SHARING)
    for b in runconfig.load(root=REPO)["budgets"].values():
        assert set(b["policy"]["seeds"]) == set(architectures.NAMES)


# ---------------------------------------------------------------------------- a new category

PLAN = """
import json
from embodied_snap import runconfig
from embodied_snap.plan import twin_plan
cfg = runconfig.load()
p = twin_plan(cfg["budgets"]["smoke"]["groups"], cfg["sessions"])
print(json.dumps(sorted(p[p.category == "extra"].group_id)))
"""


@pytest.mark.slow
def test_a_new_category_reaches_the_plan_and_the_dag(tmp_path):
    d = _copy(tmp_path)
    before = {w for r, w in dry_jobs(d) if r == "twin_acquire"}
    _edit(d / "embodied_snap/rawformat.py", '"pilot", "characterisation")', '"pilot", "characterisation", "extra")')
    _edit(d / "config.yaml", "{free_space: 4, target: 2, sealed: 2, pilot: 2, characterisation: 4}",
          "{free_space: 4, target: 2, sealed: 2, pilot: 2, characterisation: 4, extra: 8}")
    # after the 14 dynamics groups of the other categories, numbered on
    assert _python(d, PLAN) == [f"dyn_{n:04d}" for n in range(15, 23)]
    after = {w for r, w in dry_jobs(d) if r == "twin_acquire"}
    assert after - before == {"shard=dynamics_train-02"}  # 9 + 8 train groups: a third shard of 8


def test_every_evidence_set_has_a_separation_rule():
    """The separation policy (lineage/policy.py) is keyed by the table's names; the dynamics corpus
    by its split roles."""
    assert set(EVIDENCE) - {"dynamics"} <= set(POLICY)
    assert {"train", "validation", "sealed"} <= set(POLICY)


# ---------------------------------------------------------------------------- one home for writing results

# What the recording format writes itself: a group's three files and the raw directory's index.csv.
# Every other writer (json, parquet, the atomic write) is imported from embodied_snap.io or files;
# a writer taken from rawformat that this list does not name is refused.
RAW_WRITERS = {"write_group", "write_index"}


def _rawformat_names(text: str) -> list[tuple[str, int]]:
    """(name, line) of each name a source takes from rawformat: `from ...rawformat import name`, or
    `RF.name` where RF is the module imported under any alias."""
    tree = ast.parse(text)
    aliases, names = set(), []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if (node.module or "").split(".")[-1] == "rawformat":
                names += [(a.name, node.lineno) for a in node.names]
            else:
                aliases |= {a.asname or a.name for a in node.names if a.name == "rawformat"}
        elif isinstance(node, ast.Import):
            aliases |= {a.asname for a in node.names if a.name.endswith(".rawformat") and a.asname}
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            names.append((node.attr, node.lineno))
    return names


def _sources():
    for d in ("embodied_snap", "workflow_scripts", "bench", "tests"):
        yield from (p for p in sorted((REPO / d).rglob("*.py")) if p.name != "rawformat.py")
    for p in [REPO / "Snakefile", *sorted((REPO / "rules").glob("*.smk"))]:  # their Python import lines
        yield p


def test_no_module_writes_results_through_the_recording_format():
    from embodied_snap import rawformat

    refused = []
    for p in _sources():
        text = p.read_text()
        if p.suffix != ".py":
            text = "\n".join(ln for ln in text.splitlines() if ln.startswith(("import ", "from ")))
        for name, line in _rawformat_names(text):
            obj = getattr(rawformat, name, None)
            borrowed = callable(obj) and getattr(obj, "__module__", rawformat.__name__) != rawformat.__name__
            if name not in RAW_WRITERS and (name.startswith("write") or borrowed):
                refused.append(f"{p.relative_to(REPO)}:{line}: {name}")
    assert not refused, "writers come from embodied_snap.io, not rawformat: " + ", ".join(refused)
    # and the format writes no result of its own beyond its list
    own = {n for n, f in vars(rawformat).items() if n.startswith("write") and f.__module__ == rawformat.__name__}
    assert own == RAW_WRITERS

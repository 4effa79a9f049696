"""Each rule file reads only rules/common.smk and its own names, so it reads on its own and the
Snakefile's include order carries no meaning (docs/design.md, "Rule files").

The names are read from the rule files as Snakemake compiles them (its own parser), then Python's
ast: a module-level name is one a file binds at its top level (assignment, def, import)."""

import ast
import random
import re
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest
from snakemake.parser import parse
from snakemake.sourcecache import LocalSourceFile

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))
INCLUDE = re.compile(r'^( *)include: "(rules/[a-z_]+\.smk)"\n', re.M)


class _Sources:
    def open(self, path, mode="r"):
        return open(path.get_path_or_uri(secret_free=True), mode)


def compiled(path: Path) -> ast.Module:
    code, _ = parse(LocalSourceFile(str(path)), types.SimpleNamespace(sourcecache=_Sources()), {})
    return ast.parse(code)


def bound(tree: ast.Module) -> set[str]:
    """Names a file binds at its top level (under an `if` or `try` too: `if TWIN:` blocks)."""
    names = set()
    for s in _top(tree):
        if isinstance(s, (ast.FunctionDef, ast.ClassDef)):
            names.add(s.name)
        elif isinstance(s, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in s.names}
        elif isinstance(s, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            for t in s.targets if isinstance(s, ast.Assign) else [s.target]:
                names |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
    return names


def _top(tree):
    """Statements at module level, and inside module-level `if`/`try` blocks."""
    out, todo = [], list(tree.body)
    while todo:
        s = todo.pop()
        out.append(s)
        if isinstance(s, (ast.If, ast.Try)):
            todo += s.body + s.orelse + getattr(s, "finalbody", []) + [
                b for h in getattr(s, "handlers", []) for b in h.body
            ]
    return out


def used(tree: ast.Module) -> set[str]:
    return {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}


def files(root: Path = ROOT) -> dict[str, Path]:
    return {"Snakefile": root / "Snakefile", **{p.name: p for p in sorted((root / "rules").glob("*.smk"))}}


def crossings(root: Path = ROOT) -> dict[tuple[str, str], set[str]]:
    """(reader, definer) -> the names `reader` reads that `definer` binds, where `definer` is not
    common.smk (or `reader` is common.smk itself): the couplings this test refuses."""
    trees = {n: compiled(p) for n, p in files(root).items()}
    binds = {n: bound(t) for n, t in trees.items()}
    out = {}
    for reader, tree in trees.items():
        for definer, names in binds.items():
            if definer == reader or (definer == "common.smk" and reader != "common.smk"):
                continue
            hit = (used(tree) & names) - binds[reader]
            if hit:
                out[(reader, definer)] = hit
    return out


def test_each_rule_file_reads_only_common_and_its_own_names():
    assert crossings() == {}


def test_no_name_is_bound_in_two_rule_files():
    binds = {n: bound(compiled(p)) for n, p in files().items()}
    seen = {}
    for n, names in binds.items():
        for name in names - {"sys", "os", "Path", "re", "glob"}:
            if not name.startswith("__userule_"):  # Snakemake's own name for a `use rule` statement
                seen.setdefault(name, []).append(n)
    assert {k: v for k, v in seen.items() if len(v) > 1} == {}


def test_the_check_sees_a_name_read_across_files(tmp_path):
    """The check itself can fail: a rule file reading another stage's global is caught."""
    for p in ("Snakefile", "rules"):
        (shutil.copytree if (ROOT / p).is_dir() else shutil.copy)(ROOT / p, tmp_path / p)
    ablation = tmp_path / "rules/ablation.smk"
    ablation.write_text(ablation.read_text() + '\nX_OF_ABLATION = DYNAMICS_SEEDS\n')
    assert crossings(tmp_path) == {("ablation.smk", "dynamics.smk"): {"DYNAMICS_SEEDS"}}


def test_the_resampled_shards_path_is_spelled_once():
    """The grid's folder (results/data/50hz/, from protocol.GRID_HZ) is built in common.smk alone;
    every other file names the shards through RESAMPLED_SHARD."""
    spelled = {n for n, p in files().items() if re.search(r"results/data/[^\"']*hz", p.read_text())}
    assert spelled == {"common.smk"}
    readers = {n for n, p in files().items() if "RESAMPLED_SHARD" in used(compiled(p))}
    assert {"Snakefile", "data.smk", "dynamics.smk", "policy.smk", "ablation.smk"} <= readers


# --- parsing on its own, and in any order ----------------------------------------------------------


def reused(smk: Path) -> list[str]:
    """Rule files whose rules this one reuses (`use rule X as Y`): Snakemake needs X defined first."""
    rules_of = {
        p.name: set(re.findall(r"^ *(?:rule|checkpoint) (\w+):", p.read_text(), re.M))
        for p in (ROOT / "rules").glob("*.smk")
    }
    wanted = set(re.findall(r"^use rule (\w+) as", smk.read_text(), re.M))
    return sorted(f"rules/{f}" for f, rs in rules_of.items() if rs & wanted and f != smk.name)


def _copy(dst: Path) -> Path:
    dst.mkdir()
    for p in ("Snakefile", "config.yaml", "rules", "workflow_scripts", "embodied_snap", "schemas",
              "reference", "report", "envs", "profiles"):
        src = ROOT / p
        if src.is_dir():
            shutil.copytree(src, dst / p, ignore=shutil.ignore_patterns("__pycache__"))
        elif src.exists():
            shutil.copy(src, dst / p)
    return dst


def _snakemake(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([SNAKEMAKE, "--config", "budget=smoke", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_each_rule_file_parses_with_common_alone(tmp_path):
    work = _copy(tmp_path / "w")
    head = (ROOT / "Snakefile").read_text().split('include: "rules/common.smk"')[0]
    for smk in sorted((ROOT / "rules").glob("*.smk")):
        if smk.name == "common.smk":
            continue
        includes = ["rules/common.smk", *reused(smk), f"rules/{smk.name}"]
        (work / "Snakefile").write_text(head + "".join(f'include: "{i}"\n' for i in includes))
        r = _snakemake(work, "--list-rules")
        assert r.returncode == 0, f"{smk.name} with {includes[:-1]}: {(r.stdout + r.stderr)[-2000:]}"


def _job_counts(out: str) -> dict[str, int]:
    """The dry run's job table: rule -> jobs."""
    table = out.split("Job stats:")[1].split("\n\n")[0]
    return {m[0]: int(m[1]) for m in re.findall(r"^(\w+)\s+(\d+)$", table, re.M) if m[0] != "total"}


@pytest.mark.slow
def test_the_include_order_does_not_matter(tmp_path):
    work = _copy(tmp_path / "w")
    snakefile = (ROOT / "Snakefile").read_text()
    block = [m for m in INCLUDE.finditer(snakefile) if m[2] != "rules/common.smk"]
    first, last = snakefile.index('if config["raw_data"]["source"] == "twin":'), block[-1].end()
    assert first < block[0].start()
    indented = [m for m in block if m[1]]  # the twin's acquisition, under `if TWIN:`
    assert [m[2] for m in indented] == ["rules/acquire.smk"]
    stages = [m[2] for m in block if not m[1]]

    def run(order):
        body = snakefile[:first] + "".join(
            f'if TWIN:\n\n    include: "{s}"\n\n\n' if s == "rules/acquire.smk" else f'include: "{s}"\n'
            for s in order) + snakefile[last:]
        (work / "Snakefile").write_text(body)
        r = _snakemake(work, "-n", "all", "robustness")
        assert r.returncode == 0, f"order {order}: {(r.stdout + r.stderr)[-2000:]}"
        return _job_counts(r.stdout)

    want = run(["rules/acquire.smk", *stages])
    assert "policy_search" in want and "robustness_search_uniform" in want
    rng = random.Random(26)
    for _ in range(2):
        order = ["rules/acquire.smk", *stages]
        rng.shuffle(order)
        # the one order Snakemake itself imposes: a reused rule is defined before its reuse
        for smk in list(order):
            for dep in reused(ROOT / smk):
                if order.index(dep) > order.index(smk):
                    order.remove(dep)
                    order.insert(order.index(smk), dep)
        assert run(order) == want, order

"""envs/esnap.yaml, the environment a cluster job runs in (snakemake --sdm conda): runtime pins
only, the same versions as requirements.lock, closed under the pins' own requirements, and every
module a rule's code imports is provided by a listed distribution.

`--sdm conda` cannot run here (no conda channels) and building a venv from PyPI would take minutes,
so this checks, without installing, what a fresh environment built from the pip list would import:
the third-party imports of every rule's code inputs (the script and the package modules it reaches,
lineage/imports.py), mapped to their distributions."""

import ast
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from embodied_snap.lineage.dag import rule_table
from embodied_snap.lineage.imports import EXEMPT, module_file

REPO = Path(__file__).resolve().parents[1]
ENV = REPO / "envs/esnap.yaml"
# Python and pip provide these in any environment; the pins never name them.
BUILTIN = {"pip", "setuptools", "wheel"}


def _pins(lines) -> dict[str, str]:
    out = {}
    for ln in lines:
        ln = ln.strip()
        if ln and not ln.startswith("#"):
            name, version = ln.split("==")
            out[canonicalize_name(name)] = version
    return out


@pytest.fixture(scope="module")
def env() -> dict[str, str]:
    deps = yaml.safe_load(ENV.read_text())["dependencies"]
    return _pins(next(d["pip"] for d in deps if isinstance(d, dict)))


def test_pins_match_the_lock(env):
    lock = _pins((REPO / "requirements.lock").read_text().splitlines())
    assert {n: v for n, v in env.items() if lock.get(n) != v} == {}


def test_no_dev_tools(env):
    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    dev = {canonicalize_name(Requirement(r).name) for r in extras["dev"]} | {"black"}
    assert not dev & set(env)


def test_closed_under_requirements(env):
    """Every requirement of a listed distribution (as installed here) is listed: pip resolves
    nothing beyond the pins; and pyproject's dependencies are all there."""
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    missing = {canonicalize_name(Requirement(d).name) for d in deps} - set(env)
    for name in env:
        for s in metadata.distribution(name).requires or []:
            r = Requirement(s)
            if r.marker and not r.marker.evaluate({"extra": ""}):
                continue
            if canonicalize_name(r.name) not in env and canonicalize_name(r.name) not in BUILTIN:
                missing.add(f"{r.name} (for {name})")
    assert not missing


def _third_party(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return {m for m in out if m not in sys.stdlib_module_names and m != "embodied_snap"}


def test_every_rule_code_import_resolves_to_a_listed_distribution(env):
    table = rule_table(REPO, config_overrides={"budget": "smoke"})
    files = {REPO / f for t in table.values() for f in t["code"] or []}
    files |= {REPO / "workflow_scripts" / t["script"] for t in table.values() if t["script"]}
    files |= {module_file(m, REPO) for m in EXEMPT}  # the bookkeeping every job loads
    assert len(files) > 50
    dists = metadata.packages_distributions()
    unresolved = {}
    for f in sorted(files):
        for mod in _third_party(f):
            names = {canonicalize_name(d) for d in dists.get(mod, [])}
            if not names & set(env):
                unresolved[mod] = f.relative_to(REPO).as_posix()
    assert unresolved == {}


def test_the_package_itself_comes_from_the_repository():
    """The environment installs embodied_snap (editable, no dependencies beyond the pins) from the
    workflow directory, where Snakemake runs the post-deploy script."""
    script = (REPO / "envs/esnap.post-deploy.sh").read_text()
    assert re.search(r"^python -m pip install --no-deps -e \.$", script, re.M)

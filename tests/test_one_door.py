"""Each config value enters a job through one door: its rule's params (docs/design.md, "Config").

No workflow script reads `snakemake.config` (a value read there would not rerun the job when it
changes), and each key under `gate.*` and `resample.*` changes the params of exactly the rules
whose scripts use it: the gate's limits (`Limits`) or the protocol's sampling section. Which
scripts use them is read from their sources and the package modules they load, never typed here.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest
import yaml

from embodied_snap.lineage.dag import _workflow

from importprobe import loaded_by_scripts

REPO = Path(__file__).resolve().parent.parent
SCRIPTS = sorted((REPO / "workflow_scripts").glob("*.py"))
CONFIG = yaml.safe_load((REPO / "config.yaml").read_text())
COPY = ["Snakefile", "config.yaml", "rules", "workflow_scripts", "schemas", "envs", "profiles", "reference",
        "report", "embodied_snap"]


def reads_config(source: str) -> list[int]:
    """Lines where a script reads `snakemake.config` (or getattr(snakemake, "config"))."""
    lines = []
    for n in ast.walk(ast.parse(source)):
        if isinstance(n, ast.Attribute) and n.attr == "config" and isinstance(n.value, ast.Name) \
                and n.value.id == "snakemake":
            lines.append(n.lineno)
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "getattr" and \
                len(n.args) > 1 and isinstance(n.args[0], ast.Name) and n.args[0].id == "snakemake" and \
                isinstance(n.args[1], ast.Constant) and n.args[1].value == "config":
            lines.append(n.lineno)
    return lines


def test_reads_config_finds_a_read():
    assert reads_config("x = Limits.from_config(snakemake.config)\n") == [1]
    assert reads_config("c = getattr(snakemake, 'config')\n") == [1]
    assert reads_config("c = snakemake.params.config\n") == []


def test_no_script_reads_snakemake_config():
    found = {p.name: reads_config(p.read_text()) for p in SCRIPTS}
    assert SCRIPTS and not {k: v for k, v in found.items() if v}


# --- which rules use which keys ---------------------------------------------------------------


def _names(tree) -> tuple[set, set]:
    """(names, attribute names) a module's source uses."""
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    attrs = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    return names, attrs


def users(root: Path) -> dict[str, set[str]]:
    """{"gate": scripts that build the gate's Limits, "sampling": scripts that use the protocol's
    sampling section, in their own source or a package module they load, or the Limits (which
    carry the sampling values the gate checks against)}."""
    loads = loaded_by_scripts(root)
    module_attrs = {}
    out = {"gate": set(), "sampling": set()}
    for p in sorted((root / "workflow_scripts").glob("*.py")):
        names, attrs = _names(ast.parse(p.read_text()))
        for m in loads[p.name]:
            if m not in module_attrs:
                module_attrs[m] = _names(ast.parse((root / m).read_text()))[1]
            attrs |= module_attrs[m]
        if "Limits" in names:
            out["gate"].add(p.name)
            out["sampling"].add(p.name)
        if "sampling" in attrs:
            out["sampling"].add(p.name)
    return out


def changed(v):
    """Another valid value: a number half again as large, a list without its last item, a mapping
    with its first entry changed."""
    if isinstance(v, bool):
        return not v
    if isinstance(v, (int, float)):
        return v * 1.5
    if isinstance(v, list):
        return v[:-1]
    if isinstance(v, dict):
        k = next(iter(v))
        return {**v, k: changed(v[k])}
    raise TypeError(v)


# resample.max_gap_s moves the `sampling` section; its rate is no key (protocol.GRID_HZ).
KEYS = [(s, k) for s in ("gate", "resample") for k in CONFIG[s]]


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    d = tmp_path_factory.mktemp("door")
    for name in COPY:
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(
            src, d / name, **({"ignore": shutil.ignore_patterns("__pycache__")} if src.is_dir() else {})
        )
    return d


def rule_params(root: Path, overrides: dict) -> dict[str, tuple[dict, str | None]]:
    """{rule: ({param: repr of its value} for the params that are values, its script)}."""
    with _workflow(root, None, {"budget": "smoke", **overrides}) as wf_api:
        out = {}
        for r in wf_api._workflow.rules:
            vals = {k: repr(v) for k, v in r.params.items() if not callable(v)}
            out[r.name] = (vals, Path(r.script).name if r.script else None)
        return out


@pytest.fixture(scope="module")
def base(tree):
    return rule_params(tree, {})


@pytest.fixture(scope="module")
def used(tree):
    return users(tree)


@pytest.mark.slow
@pytest.mark.parametrize("section, key", KEYS, ids=[f"{s}.{k}" for s, k in KEYS])
def test_a_changed_key_changes_the_params_of_exactly_the_rules_that_use_it(tree, base, used, section, key):
    value = changed(CONFIG[section][key])
    after = rule_params(tree, {section: {**CONFIG[section], key: value}})
    moved = {r for r, (p, _) in after.items() if p != base[r][0]}
    who = "gate" if section == "gate" else "sampling"
    expected = {r for r, (_, script) in base.items() if script in used[who]}
    assert expected
    assert moved == expected, (f"{section}.{key}: params change without a use: {sorted(moved - expected)}; "
                               f"used without a params entry: {sorted(expected - moved)}")


# --- one home: config.yaml, the schema holds no second copy -------------------------------------

SCHEMA = yaml.safe_load((REPO / "schemas" / "config.schema.yaml").read_text())


def defaults(node, where="schema") -> list[str]:
    """Where the loaded schema has a `default:` (at any depth, definitions included)."""
    found = []
    if isinstance(node, dict):
        if "default" in node:
            found.append(where)
        for k, v in node.items():
            found += defaults(v, f"{where}.{k}")
    elif isinstance(node, list):
        for i, v in enumerate(node):
            found += defaults(v, f"{where}[{i}]")
    return found


def test_the_schema_has_no_defaults_and_config_yaml_passes_it_unchanged():
    import copy

    import jsonschema
    from snakemake.utils import validate

    assert defaults({"a": [{"default": 1}]}) == ["schema.a[0]"]  # the walk finds one
    assert defaults(SCHEMA) == []
    jsonschema.validate(CONFIG, SCHEMA)
    cfg = copy.deepcopy(CONFIG)
    validate(cfg, str(REPO / "schemas" / "config.schema.yaml"))  # as the Snakefile: set_default=True
    assert cfg == CONFIG


def leaves(d: dict, path=()) -> list[tuple]:
    """Every leaf key path of a config: a key whose value is not a non-empty mapping."""
    out = []
    for k, v in d.items():
        out += leaves(v, (*path, k)) if isinstance(v, dict) and v else [(*path, k)]
    return out


def schema_node(path: tuple) -> dict:
    """The schema of the value at `path` ($refs followed; a name-keyed map's entries share one)."""
    node = SCHEMA
    for k in path:
        while "$ref" in node:
            node = SCHEMA["definitions"][node["$ref"].split("/")[-1]]
        node = node["properties"][k] if k in node.get("properties", {}) else node["additionalProperties"]
    while "$ref" in node:
        node = SCHEMA["definitions"][node["$ref"].split("/")[-1]]
    return node


# Entries of name-keyed maps (no `properties` in the schema; their names live elsewhere) whose absence
# the code handles, so deleting one is a valid config: "*" is any name.
OPTIONAL = {
    ("budgets", "*", "groups", "*", "*"): "a category a budget does not ask for is not recorded (plan.twin_plan)",
    ("gate", "labels", "*"): "a <set>/<category> entry falls back to its set's; a set without one has its "
                             "recordings refused by the gate (validate.py, 'no gate.labels entry')",
    ("gate", "program", "*"): "as gate.labels",
    ("policy", "robustness", "budget_factors", "*"): "the variants are the config's choice (at least one)",
}


def optional(path: tuple) -> bool:
    return any(len(p) == len(path) and all(a in ("*", b) for a, b in zip(p, path)) for p in OPTIONAL)


LEAVES = leaves(CONFIG)


def without(path: tuple) -> dict:
    import copy

    cfg = copy.deepcopy(CONFIG)
    d = cfg
    for k in path[:-1]:
        d = d[k]
    del d[path[-1]]
    return cfg


def test_the_leaves_are_every_key_and_the_optional_ones_are_map_entries():
    assert len(LEAVES) > 150 and ("raw_data", "exclude") in LEAVES and ("gate", "program", "deployment") in LEAVES
    assert ("budgets", "paper", "policy", "seeds", "shared") in LEAVES  # a map entry the names check requires
    for p in OPTIONAL:
        assert any(optional(q) and len(q) == len(p) for q in LEAVES), p  # each pattern matches a leaf
    for path in filter(optional, LEAVES):
        assert "properties" not in schema_node(path[:-1]), path  # a name-keyed map, never a fixed key


@pytest.mark.parametrize("path", [p for p in LEAVES if not optional(p)], ids=".".join)
def test_a_config_without_any_one_key_is_refused_in_one_line_naming_it(path):
    from embodied_snap import runconfig

    with pytest.raises(runconfig.ConfigError) as e:
        runconfig.validate(without(path))
    says = str(e.value)
    assert "\n" not in says and f"'{path[-1]}'" in says and "required" in says, says


@pytest.mark.parametrize("path", [p for p in LEAVES if optional(p)], ids=".".join)
def test_a_config_without_an_optional_map_entry_is_valid(path):
    from embodied_snap import runconfig

    runconfig.validate(without(path))

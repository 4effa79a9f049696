"""The pipeline does not depend on the simulated rig (issue 10). Package modules are held to it by
the import-linter contract in pyproject.toml (`lint-imports`, run by .ci/run); workflow scripts are
not a package, so this test reads their imports: only the acquisition and twin-report scripts may
import embodied_snap.twin, and none the lab client (embodied_snap.lab)."""

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
# The scripts of rules/acquire.smk, included only with raw_data.source: twin (Fig. 1a's render of the
# simulated rig's model among them).
TWIN_SCRIPTS = {"twin_acquire", "twin_index", "twin_truth", "twin_phenomena", "twin_validation", "twin_deployment",
                "twin_render"}


def imported_modules(path: Path) -> set[str]:
    mods = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            mods |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            mods.add(node.module)
            mods |= {f"{node.module}.{a.name}" for a in node.names}
    return mods


def twin_importers(scripts) -> set[str]:
    return {p.stem for p in scripts
            if any(m == "embodied_snap.twin" or m.startswith("embodied_snap.twin.") for m in imported_modules(p))}


def test_only_acquisition_scripts_import_the_twin():
    scripts = sorted((REPO / "workflow_scripts").glob("*.py"))
    assert scripts
    assert twin_importers(scripts) - TWIN_SCRIPTS == set()


def test_the_check_sees_every_import_form(tmp_path):
    forms = ["from embodied_snap.twin.acquire import acquire_groups", "import embodied_snap.twin.sim",
             "from embodied_snap.twin import acquire", "from embodied_snap import twin"]
    for k, line in enumerate(forms):
        (tmp_path / f"s{k}.py").write_text(line + "\n")
    (tmp_path / "ok.py").write_text("from embodied_snap.primitive import release_goals\nimport embodied_snap.twinkle\n")
    assert twin_importers(tmp_path.glob("*.py")) == {f"s{k}" for k in range(len(forms))}


def lab_importers(scripts) -> set[str]:
    return {p.stem for p in scripts
            if any(m == "embodied_snap.lab" or m.startswith("embodied_snap.lab.") for m in imported_modules(p))}


def test_no_workflow_script_imports_the_lab_client(tmp_path):
    """The lab client (esnap lab) drives the arm; the pipeline reads what it recorded, never runs it."""
    assert lab_importers(sorted((REPO / "workflow_scripts").glob("*.py"))) == set()
    for k, line in enumerate(["from embodied_snap.lab import acquire", "import embodied_snap.lab.plan"]):
        (tmp_path / f"s{k}.py").write_text(line + "\n")
    (tmp_path / "ok.py").write_text("import embodied_snap.labels\n")
    assert lab_importers(tmp_path.glob("*.py")) == {"s0", "s1"}

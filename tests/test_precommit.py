"""The pre-commit hooks run the same checks as CI: every `.venv/bin/TOOL ...` check line of .ci/run
has a hook running that tool with the same arguments."""

from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parent.parent


def ci_checks() -> set[str]:
    """Each check of .ci/run as `TOOL ARGS`, less the paths it is given (hooks are given files)."""
    return {" ".join(w for w in ln.split() if not (REPO / w).exists()).removeprefix(".venv/bin/")
            for ln in (REPO / ".ci/run").read_text().splitlines() if ln.startswith(".venv/bin/")}


def test_every_ci_check_is_a_hook():
    hooks = yaml.safe_load((REPO / ".pre-commit-config.yaml").read_text())["repos"][0]["hooks"]
    entries = " | ".join(h["entry"] for h in hooks)
    checks = ci_checks()
    assert checks == {"lint-imports", "snakemake --lint", "snakefmt --check", "ruff check"}, checks
    for c in checks:
        assert f".venv/bin/{c}" in entries, c

"""The pre-commit hooks run the same checks as CI: every `.venv/bin/TOOL ...` check line of .ci/run
has a hook running that tool with the same arguments."""

from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parent.parent


def ci_checks() -> set[str]:
    """Each check of .ci/run as `TOOL ARGS`, less the paths it is given (hooks are given files)."""
    lines = [ln.split() for ln in (REPO / ".ci/run").read_text().splitlines() if ln.startswith(".venv/bin/")]
    return {" ".join([w[0].removeprefix(".venv/bin/"), *(x for x in w[1:] if not (REPO / x).exists())])
            for w in lines}


def test_every_ci_check_is_a_hook():
    hooks = yaml.safe_load((REPO / ".pre-commit-config.yaml").read_text())["repos"][0]["hooks"]
    entries = " | ".join(h["entry"] for h in hooks)
    checks = ci_checks()
    assert checks == {"lint-imports", "snakemake --lint", "snakefmt --check", "ruff check"}, checks
    for c in checks:
        assert f".venv/bin/{c}" in entries, c

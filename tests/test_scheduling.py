"""embodied_snap/scheduling.py: a local run schedules once per finished job, not once a second per
finished job (Snakemake 9.27's job rate limiter re-arms a timer after every round)."""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).parent / "snakemake"
JOBS = 12

SNAKEFILE = f"""
import sys
sys.path.insert(0, {str(REPO)!r})
from embodied_snap.scheduling import local_runs_without_rate_limit
if config.get("patch"):
    local_runs_without_rate_limit()
rule all:
    input: expand("o/{{i}}", i=range({JOBS}))
rule one:
    output: "o/{{i}}"
    shell: "sleep 0.3; touch {{output}}"
"""


def rounds(tmp_path: Path, patch: int) -> int:
    """Scheduling rounds that found ready jobs (Snakemake's debug line 'Ready jobs: N'), one core."""
    d = tmp_path / f"patch{patch}"
    d.mkdir()
    (d / "Snakefile").write_text(SNAKEFILE)
    r = subprocess.run([str(SNAKEMAKE), "--cores", "1", "--verbose", "--config", f"patch={patch}"], cwd=d,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert len(list((d / "o").iterdir())) == JOBS
    return (r.stdout + r.stderr).count("Ready jobs:")


@pytest.mark.slow
def test_a_local_run_schedules_once_per_finished_job(tmp_path):
    # a round per job: the first, then one per finished job (the last one readies the target `all`)
    assert rounds(tmp_path, 1) == JOBS + 1
    # Snakemake's own: the timers pile up while jobs wait (if this fails, an upgrade fixed it and
    # embodied_snap/scheduling.py can go)
    assert rounds(tmp_path, 0) > JOBS + 6


def test_the_patch_is_applied_once():
    from snakemake.scheduling.job_scheduler import JobScheduler

    from embodied_snap.scheduling import local_runs_without_rate_limit

    local_runs_without_rate_limit()
    patched = JobScheduler.__init__
    local_runs_without_rate_limit()
    assert JobScheduler.__init__ is patched and patched.esnap_local_unlimited

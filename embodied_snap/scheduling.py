"""One change to Snakemake's local scheduler, made when the workflow is read (the Snakefile).

Snakemake 9.27 limits how many jobs start per timespan (`--max-jobs-per-timespan`, 100/1s by
default) and, after every scheduling round that leaves a ready job waiting, arms a timer that runs
another round one timespan later, whether the limit held anything back or not. Every finished job
starts a round of its own, so while jobs wait for cores the timers pile up: after N finished jobs,
N rounds a second, each one stat-ing the inputs of every ready job and selecting jobs again
(upstream: snakemake pull request #3744). A local run never starts 100 jobs in a second, so it runs
without the limit, and a round comes only when a job finishes; a cluster run (an executor plugin)
keeps it. Jobs, their order and their results are unchanged (docs/design.md, "Scheduling");
`tests/test_scheduling.py` fails when an upgrade of Snakemake moves what this relies on.
"""

from __future__ import annotations


def local_runs_without_rate_limit() -> None:
    """Patch Snakemake's JobScheduler once per process: a local run has no job rate limiter."""
    from snakemake.scheduling.job_scheduler import JobScheduler

    init = JobScheduler.__init__
    if getattr(init, "esnap_local_unlimited", False):
        return

    def __init__(self, *args, **kwargs):
        init(self, *args, **kwargs)
        if self.workflow.local_exec:
            self.job_rate_limiter = None

    __init__.esnap_local_unlimited = True
    JobScheduler.__init__ = __init__

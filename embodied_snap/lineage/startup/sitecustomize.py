"""The start-up hook of a workflow's jobs (docs/lineage.md, "From the interpreter's start").

The workflow puts this folder first on its jobs' PYTHONPATH (records.job_environment, called by
rules/common.smk), so every Python a job starts imports this module at start-up, before its main
module. In the interpreter of a Snakemake `script:` job, which runs Snakemake's copy of the script
(.snakemake/scripts/tmpXXXX.<name>.py), it starts the watch of the job's reads before the script's
first line; any other Python (snakemake itself, a shell command, a worker) pays one string test.
A sitecustomize further down the path (a distribution's, a test's), which this one hides, still runs.
Standard library only until it knows it is in a job; not a package module, so never a code input.
"""

import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))

if sys.argv and os.path.dirname(os.path.abspath(sys.argv[0])).endswith(os.path.join(".snakemake", "scripts")):
    from embodied_snap.lineage import records

    records.watch_from_start()

import importlib.machinery  # noqa: E402 -- after the watch, so what the next hook reads is seen

_next = importlib.machinery.PathFinder.find_spec(
    "sitecustomize", [p for p in sys.path if os.path.abspath(p) != _HERE])
if _next is not None:
    import importlib.util  # noqa: E402

    _next.loader.exec_module(importlib.util.module_from_spec(_next))

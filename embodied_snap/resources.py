"""Cluster resources from measurements: each benchmarked rule's `mem_mb`, `runtime` and
`cpus_per_task`, from the `benchmarks/*.tsv` of a paper-budget run (docs/cluster.md).

`esnap resources --benchmarks DIR` writes them into the `set-resources` of profiles/slurm, so they
follow the code after a change: rerun the paper budget, rerun the command, commit the profile.

- mem_mb: the largest `max_rss` of the rule's jobs times MEM_MARGIN, rounded up to MEM_STEP, at
  least MEM_MIN (a node's page cache and a second import of torch must fit).
- runtime (minutes): the longest wall time `s` times TIME_MARGIN, rounded up, at least RUNTIME_MIN
  (a job's start on a busy node, Snakemake's own start, a slower file system).
- cpus_per_task: the rule's `threads:` (read from the workflow, never typed), so SLURM gives a job
  the cores its torch/BLAS threads use.

Rules without a benchmark are tiny bookkeeping jobs: the profile's `default-resources` cover them,
and so they cover the rules written once per shard (the acquisition, seconds a shard): their names
follow a budget's shards, which the profile cannot list.
A benchmarked rule the run did not execute (a stage added since, or a target outside `all`) is
listed in the profile as not measured and gets the default too, until a run measures it.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

MEM_MARGIN = 1.5
MEM_STEP = 100  # MB
MEM_MIN = 1000  # MB
TIME_MARGIN = 2.0
RUNTIME_MIN = 5  # minutes
# The generated part of the profile starts at this line; everything above it is written by hand.
MARKER = "# --- Written by `esnap resources` from a paper-budget run's benchmarks; do not edit below."


class ResourceError(ValueError):
    """A benchmark tree that cannot give resources: one line naming the file or rule."""


def read_benchmark(path: Path) -> tuple[float, float]:
    """(wall seconds, max RSS in MB) of one Snakemake benchmark file (the largest over repeats)."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f, delimiter="\t"))
        secs = max(float(r["s"]) for r in rows)
        rss = max(float(r["max_rss"]) if r["max_rss"] not in ("", "NA", "-") else 0.0 for r in rows)
    except (OSError, KeyError, ValueError) as e:
        raise ResourceError(f"{path}: not a Snakemake benchmark file ({type(e).__name__}: {e})") from None
    return secs, rss


def measure(bench_dir: str | Path, patterns: dict[str, str]) -> tuple[dict[str, tuple[float, float]], list[str]]:
    """({rule: (longest wall seconds, largest max RSS MB)}, [rules with no file]) over the benchmark
    files under bench_dir. `patterns`: {rule: regex of its benchmark path, relative to the workflow
    root}. A file no rule writes (a renamed rule) is an error."""
    bench_dir = Path(bench_dir)
    regexes = {r: re.compile(p) for r, p in patterns.items()}
    # Patterns start with the workflow's "benchmarks/"; match files by their path under bench_dir.
    found: dict[str, list[tuple[float, float]]] = {r: [] for r in patterns}
    for f in sorted(bench_dir.rglob("*.tsv")):
        rel = "benchmarks/" + f.relative_to(bench_dir).as_posix()
        rules = [r for r, rx in regexes.items() if rx.match(rel)]
        if not rules:
            raise ResourceError(f"{f}: matches no rule's benchmark: (a renamed or removed rule?)")
        for r in rules:
            found[r].append(read_benchmark(f))
    missing = sorted(r for r, v in found.items() if not v)
    return {r: (max(s for s, _ in v), max(m for _, m in v)) for r, v in found.items() if v}, missing


def rule_resources(secs: float, rss_mb: float, threads: int) -> dict[str, int]:
    """The SLURM request of one rule from its measurements (margins above)."""
    mem = max(MEM_MIN, MEM_STEP * math.ceil(rss_mb * MEM_MARGIN / MEM_STEP))
    runtime = max(RUNTIME_MIN, math.ceil(secs * TIME_MARGIN / 60))
    return dict(mem_mb=int(mem), runtime=int(runtime), cpus_per_task=int(threads))


def set_resources(bench_dir: str | Path, table: dict[str, dict], per_shard=frozenset()
                  ) -> tuple[dict[str, dict[str, int]], list[str]]:
    """({rule: {mem_mb, runtime, cpus_per_task}}, [benchmarked rules not measured]) for the
    benchmarked rules of `table` (lineage.dag.rule_table: each rule's benchmark regex and threads);
    the rules `per_shard` get default-resources (above): their benchmark files are matched, so
    that none counts as a stranger, and their measurements dropped."""
    patterns = {r: t["benchmark"] for r, t in table.items() if t.get("benchmark")}
    measured, missing = measure(bench_dir, patterns)
    measured = {r: v for r, v in measured.items() if r not in per_shard}
    missing = [r for r in missing if r not in per_shard]
    out = {}
    for r in sorted(measured):
        threads = table[r].get("threads")
        if not isinstance(threads, int):
            raise ResourceError(f"rule {r}: threads is not a number in the workflow (a function?)")
        out[r] = rule_resources(*measured[r], threads)
    return out, missing


NOT_MEASURED = "# Not measured by these benchmarks (default-resources apply): "


def render(resources: dict[str, dict[str, int]], missing: list[str] = ()) -> str:
    """The generated tail of the profile: the marker, the margins used, the rules not measured, and
    `set-resources`."""
    lines = [MARKER,
             f"# mem_mb = max RSS x {MEM_MARGIN} (>= {MEM_MIN}, step {MEM_STEP}), "
             f"runtime = wall time x {TIME_MARGIN} in minutes (>= {RUNTIME_MIN}),",
             "# cpus_per_task = the rule's threads.",
             *([NOT_MEASURED + ", ".join(missing)] if missing else []),
             "set-resources:"]
    for r, res in resources.items():
        lines.append(f"  {r}:")
        lines += [f"    {k}: {v}" for k, v in res.items()]
    return "\n".join(lines) + "\n"


def updated_profile(profile_text: str, tail: str) -> str:
    """The profile with its generated part (from MARKER on) replaced by `tail`."""
    head = profile_text.split(MARKER, 1)[0].rstrip("\n")
    return f"{head}\n\n{tail}" if head else tail


def not_measured(profile_text: str) -> list[str]:
    """The rules the profile lists as not measured."""
    for line in profile_text.splitlines():
        if line.startswith(NOT_MEASURED):
            return [r.strip() for r in line[len(NOT_MEASURED):].split(",")]
    return []

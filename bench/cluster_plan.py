"""A measured run replayed on a cluster: its critical path and its wall time on N nodes.

    python bench/cluster_plan.py .snakemake/log/<run>.snakemake.log [--root .]
        [--profile profiles/slurm/config.yaml] [--node-cores 2] [--nodes 1 2 4 8 16 32]
        [--overhead-s 0] [--png plan.png]

It plans; it is no scheduler. From the run's log (bench/timeline.py) each job's rule, wildcards,
inputs, outputs, priority and threads; its time is its benchmark file's wall time (`s`) where it has
one, else the log's (whole seconds). A job waits for the jobs that wrote its inputs: a declared output,
a file under a declared output folder, or, in the log of a run from before the acquisition became a
rule per shard, a recording an acquisition checkpoint wrote (its `results/twin/acquired/<shard>.json`
lists the groups). The profile's `groups` join connected jobs of
one group into one cluster job (their times summed, their threads the largest), as Snakemake submits
them. `--overhead-s` is added to every cluster job (submission and status polling).

Prints the critical path (the wall time on unlimited nodes) and the chain that sets it, then for each
N the planned wall time, its ratio to the critical path and to the packing floor (job-seconds / all
cores). The plan is list scheduling: whenever a job ends, the ready jobs in Snakemake's order
(priority, then the order the run started them) each go to the first node with enough free cores.
"""

from __future__ import annotations

import argparse
import heapq
import json
from pathlib import Path

import pandas as pd
import yaml
from timeline import jobs as logged

ROOT = Path(__file__).resolve().parent.parent


def durations(js: list[dict], root: Path) -> list[float]:
    out = []
    for j in js:
        b = root / j["benchmark"] if j["benchmark"] else None
        out.append(float(pd.read_csv(b, sep="\t")["s"].iloc[-1]) if b and b.exists() else j["end"] - j["start"])
    return out


def producers(js: list[dict], root: Path) -> dict[str, int]:
    """file or folder -> index of the job that wrote it."""
    made = {}
    for i, j in enumerate(js):
        for f in j["output"]:
            made[f.rstrip("/")] = i
            p = root / f
            if f.startswith("results/twin/acquired/") and p.exists():  # an older run's checkpoint recordings
                for g in json.loads(p.read_text()).get("groups", []):
                    made[f"raw_data/groups/{g['group_id']}"] = i
    return made


def dependencies(js: list[dict], made: dict[str, int]) -> list[set[int]]:
    def writer(f):
        parts = f.split("/")
        for k in range(len(parts), 0, -1):  # the file itself, then each folder above it
            if (i := made.get("/".join(parts[:k]))) is not None:
                return i
        return None

    return [{w for f in j["input"] if (w := writer(f)) is not None and w != i} for i, j in enumerate(js)]


def cluster_jobs(js, dur, deps, groups: dict[str, str]) -> list[dict]:
    """Jobs joined into cluster jobs: connected jobs of one profile group are one (union-find)."""
    parent = list(range(len(js)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in enumerate(js):
        for d in deps[i]:
            if groups.get(j["rule"]) and groups.get(j["rule"]) == groups.get(js[d]["rule"]):
                parent[find(i)] = find(d)
    units: dict[int, dict] = {}
    for i, j in enumerate(js):
        u = units.setdefault(find(i), dict(members=[], s=0.0, threads=1, priority=0, order=i, deps=set()))
        u["members"].append(i)
        u["s"] += dur[i]
        u["threads"] = max(u["threads"], j["threads"])
        u["priority"] = max(u["priority"], j["priority"])
        u["order"] = min(u["order"], i)
    index = {root: k for k, root in enumerate(units)}
    out = list(units.values())
    for k, u in enumerate(out):
        u["deps"] = {index[find(d)] for i in u["members"] for d in deps[i]} - {k}
    return out


def critical_path(units: list[dict], overhead: float = 0.0) -> tuple[float, list[int]]:
    """(length, chain of unit indices): the longest path of unit times (+ overhead each)."""
    finish, via, left = {}, {}, set(range(len(units)))
    while left:  # in dependency order: a unit once all it waits for is finished
        for k in [k for k in left if units[k]["deps"] <= finish.keys()]:
            via[k] = max(units[k]["deps"], key=finish.get, default=None)
            finish[k] = (finish[via[k]] if via[k] is not None else 0.0) + units[k]["s"] + overhead
            left.remove(k)
    end = max(finish, key=finish.get)
    chain = [end]
    while via[chain[-1]] is not None:
        chain.append(via[chain[-1]])
    return finish[end], chain[::-1]


def plan(units: list[dict], nodes: int, node_cores: int, overhead: float = 0.0) -> float:
    """Wall time of list scheduling on `nodes` nodes of `node_cores` cores."""
    free = [node_cores] * nodes
    waiting = [len(u["deps"]) for u in units]
    users = [[] for _ in units]
    for k, u in enumerate(units):
        for d in u["deps"]:
            users[d].append(k)
    ready = [k for k, n in enumerate(waiting) if n == 0]
    running, t, done = [], 0.0, 0
    while done < len(units):
        ready.sort(key=lambda k: (-units[k]["priority"], units[k]["order"]))
        for k in list(ready):
            need = min(units[k]["threads"], node_cores)
            n = next((n for n in range(nodes) if free[n] >= need), None)
            if n is not None:
                free[n] -= need
                heapq.heappush(running, (t + units[k]["s"] + overhead, k, n, need))
                ready.remove(k)
        t, k, n, need = heapq.heappop(running)
        free[n] += need
        done += 1
        for v in users[k]:
            waiting[v] -= 1
            if waiting[v] == 0:
                ready.append(v)
    return t


def load(log: Path, root: Path, profile: Path | None) -> tuple[list[dict], list[dict]]:
    js = logged(log)
    groups = (yaml.safe_load(profile.read_text()) or {}).get("groups", {}) if profile else {}
    deps = dependencies(js, producers(js, root))
    return js, cluster_jobs(js, durations(js, root), deps, groups)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", type=Path)
    ap.add_argument("--root", type=Path, default=Path("."), help="the run's workflow folder")
    ap.add_argument("--profile", type=Path, default=ROOT / "profiles/slurm/config.yaml")
    ap.add_argument("--node-cores", type=int, default=2)
    ap.add_argument("--nodes", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    ap.add_argument("--overhead-s", type=float, default=0.0)
    ap.add_argument("--png", type=Path)
    a = ap.parse_args(argv)
    js, units = load(a.log, a.root, a.profile)
    job_s = sum(u["s"] * min(u["threads"], a.node_cores) for u in units)
    cp, chain = critical_path(units, a.overhead_s)
    print(f"{len(js)} jobs in {len(units)} cluster jobs; {job_s:.0f} core-seconds of jobs; overhead "
          f"{a.overhead_s:g} s a cluster job")
    print(f"critical path: {cp:.0f} s ({cp / 60:.1f} min), {len(chain)} cluster jobs:")
    for k in chain:
        u = units[k]
        names = " + ".join(dict.fromkeys(f"{js[i]['rule']}({js[i]['wildcards']})" for i in u["members"]))
        print(f"  {u['s']:8.0f} s  {names}")
    print(f"{'nodes':>5}{'wall s':>9}{'/ critical':>11}{'/ floor':>9}")
    rows = []
    for n in a.nodes:
        w = plan(units, n, a.node_cores, a.overhead_s)
        floor = max(cp, job_s / (n * a.node_cores))
        rows.append((n, w))
        print(f"{n:>5}{w:>9.0f}{w / cp:>11.2f}{w / floor:>9.2f}")
    if a.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import matplotlib.ticker

        fig, ax = plt.subplots(figsize=(4.5, 3))
        ns = [n for n, _ in rows]
        ax.plot(ns, [w / 60 for _, w in rows], "o-", color="k", label="planned wall time")
        ax.plot(ns, [job_s / (n * a.node_cores) / 60 for n in ns], ":", color="0.5", label="job-s / cores")
        ax.axhline(cp / 60, color="C3", ls="--", label="critical path")
        ax.set(xscale="log", yscale="log", xlabel=f"nodes ({a.node_cores} cores each)", ylabel="minutes")
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_yticks([t for t in (1, 2, 5, 10, 20, 50, 100, 200) if ax.get_ylim()[0] <= t <= ax.get_ylim()[1]])
        ax.legend(frameon=False, fontsize=8)
        fig.tight_layout()
        fig.savefig(a.png, dpi=150)
        print(f"wrote {a.png}")


if __name__ == "__main__":
    main()

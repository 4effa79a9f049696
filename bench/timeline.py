"""Where a workflow run's time went, from its Snakemake log: each stage's share, idle cores, a timeline.

    python bench/timeline.py .snakemake/log/<run>.snakemake.log [--cores 2] [--png timeline.png]
        [--samples load.tsv]

A job starts at the time stamp above its `rule`/`checkpoint` block and ends at the one above its
`Finished jobid` line (whole seconds, Snakemake's resolution). A stage is the rules/<stage>.smk file
that defines the rule. Prints, per stage: jobs, the first start and last end (s from the run's
start), the job-seconds, and their share of all job-seconds; then the seconds during which the
running jobs' threads took fewer cores than there are while work remained. --png draws one lane per
core, each job a bar on as many lanes as its threads, coloured by stage; --samples (t_s, load1
columns, e.g. from a sampler beside the run) adds the load average under it.
"""

from __future__ import annotations

import argparse
import datetime as dt
import re
from collections import Counter, defaultdict
from pathlib import Path

from embodied_snap.lineage.records import instance

ROOT = Path(__file__).resolve().parent.parent
STAMP = re.compile(r"^\[(\w{3} \w{3} +\d+ [\d:]+ \d{4})\]$")
START = re.compile(r"^(?:local)?(?:rule|checkpoint) ([\w-]+):$")


def logged_job(name: str) -> tuple[str, str]:
    """A rule name as Snakemake's log and dry run print it -> (rule, wildcards as they print them):
    a rule per shard (`twin_acquire_<shard>`) as its rule with the shard (lineage.records.instance)."""
    rule, wc = instance(name, {})
    return rule, ", ".join(f"{k}={v}" for k, v in wc.items())


def stages(root: Path = ROOT) -> dict[str, str]:
    """rule -> the rules/<stage>.smk defining it (the Snakefile's own rules: 'Snakefile')."""
    out = {}
    for f in [root / "Snakefile", *sorted((root / "rules").glob("*.smk"))]:
        # `rule X:`, `checkpoint X:`, a reuse `use rule Y as X with:` (rules/robustness.smk), and a
        # rule per shard named `per_shard_name("X", shard)` (rules/acquire.smk)
        pattern = r'^\s*(?:(?:rule|checkpoint|use rule \w+ as) (\w+)(?::| with:)|per_shard_name\("(\w+)")'
        for m in re.finditer(pattern, f.read_text(), re.M):
            out[m.group(1) or m.group(2)] = f.stem
    return out


def jobs(log: str | Path) -> list[dict]:
    """One dict per finished job: rule, wildcards, input and output (file lists), priority, threads,
    benchmark (its file, or None), start and end (s from the first start)."""
    ts, block, started, out = None, None, {}, []
    for line in Path(log).read_text().splitlines():
        if m := STAMP.match(line):
            ts = dt.datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y")
        elif m := START.match(line):
            rule, wildcards = logged_job(m.group(1))
            block = dict(rule=rule, wildcards=wildcards, input=[], output=[], priority=0, threads=1, benchmark=None,
                         start=ts)
        elif block and (m := re.match(r"^\s+wildcards: (.*)$", line)):
            block["wildcards"] = m.group(1)
        elif block and (m := re.match(r"^\s+(input|output): (.*)$", line)):
            block[m.group(1)] = m.group(2).split(", ")
        elif block and (m := re.match(r"^\s+(priority|threads): (\d+)$", line)):
            block[m.group(1)] = int(m.group(2))
        elif block and (m := re.match(r"^\s+benchmark: (.*)$", line)):
            block["benchmark"] = m.group(1)
        elif block and (m := re.match(r"^\s+jobid: (\d+)$", line)):
            started[int(m.group(1))] = block
        elif (m := re.match(r"^Finished jobid: (\d+)", line)) and int(m.group(1)) in started:
            out.append(dict(started.pop(int(m.group(1))), end=ts))
    if not out:
        return []
    t0 = min(j["start"] for j in out)
    for j in out:
        j["start"], j["end"] = (j["start"] - t0).total_seconds(), (j["end"] - t0).total_seconds()
    return sorted(out, key=lambda j: (j["start"], j["end"]))


def shares(js: list[dict], stage_of: dict[str, str]) -> list[dict]:
    by = defaultdict(list)
    for j in js:
        by[stage_of.get(j["rule"], "?")].append(j)
    total = sum(j["end"] - j["start"] for j in js) or 1.0
    rows = [dict(stage=s, jobs=len(v), first=min(j["start"] for j in v), last=max(j["end"] for j in v),
                 job_s=sum(j["end"] - j["start"] for j in v)) for s, v in by.items()]
    for r in rows:
        r["share"] = r["job_s"] / total
    return sorted(rows, key=lambda r: r["first"])


def occupancy(js: list[dict]) -> Counter:
    """Seconds during which the running jobs' threads took k cores, k = 0, 1, 2, ..."""
    ev = sorted([(j["start"], j["threads"]) for j in js] + [(j["end"], -j["threads"]) for j in js],
                key=lambda e: (e[0], -e[1]))
    c, cur, prev = Counter(), 0, 0.0
    for t, d in ev:
        c[cur] += t - prev
        cur, prev = cur + d, t
    return c


def lanes(js: list[dict], cores: int) -> list[list[int]]:
    """The lanes of each job, one per thread (a job on a busy lane goes to the next free one; more
    than `cores` can overlap at the log's one-second resolution)."""
    free, out = [0.0] * cores, []
    for j in js:
        ks = [i for i, f in enumerate(free) if f <= j["start"]][: j["threads"]]
        while len(ks) < j["threads"]:
            free.append(0.0)
            ks.append(len(free) - 1)
        for k in ks:
            free[k] = j["end"]
        out.append(ks)
    return out


def draw(js, stage_of, cores, png, samples=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = list(dict.fromkeys(stage_of.get(j["rule"], "?") for j in js))
    cmap = plt.get_cmap("tab20")
    colour = {s: cmap(i % 20) for i, s in enumerate(order)}
    fig, axes = plt.subplots(2 if samples else 1, 1, figsize=(9, 3.2 if samples else 2.2), sharex=True,
                             gridspec_kw={"height_ratios": [2, 1]} if samples else None, squeeze=False)
    ax = axes[0][0]
    for j, ks in zip(js, lanes(js, cores)):
        for k in ks:
            ax.barh(k, max(j["end"] - j["start"], 0.5) / 60, left=j["start"] / 60, height=0.8,
                    color=colour[stage_of.get(j["rule"], "?")], edgecolor="white", linewidth=0.3)
    ax.set_yticks(range(cores), [f"core {i + 1}" for i in range(cores)])
    ax.set_ylim(-0.6, max(cores, 1) - 0.4)
    ax.legend(handles=[plt.Rectangle((0, 0), 1, 1, color=colour[s]) for s in order], labels=order, fontsize=7,
              loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    if samples:
        t, load = samples
        axes[1][0].plot([x / 60 for x in t], load, lw=1, color="k")
        axes[1][0].set_ylabel("load avg")
    axes[-1][0].set_xlabel("minutes from the first job")
    fig.tight_layout()
    fig.savefig(png, dpi=150)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", type=Path)
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--png", type=Path)
    ap.add_argument("--samples", type=Path, help="tsv with t_s and load1 columns")
    a = ap.parse_args(argv)
    js, stage_of = jobs(a.log), stages()
    span = max(j["end"] for j in js)
    print(f"{len(js)} jobs, {span:.0f} s from the first start to the last end ({span / 60:.1f} min)")
    print(f"{'stage':<14}{'jobs':>5}{'first s':>9}{'last s':>8}{'job-s':>8}{'share':>7}")
    for r in shares(js, stage_of):
        print(f"{r['stage']:<14}{r['jobs']:>5}{r['first']:>9.0f}{r['last']:>8.0f}{r['job_s']:>8.0f}{r['share']:>7.1%}")
    occ = occupancy(js)
    idle = sum((a.cores - k) * s for k, s in occ.items() if k < a.cores)
    print("seconds with k cores taken by jobs: " + ", ".join(f"{k}: {occ[k]:.0f}" for k in sorted(occ) if occ[k] > 0))
    print(f"idle core-seconds: {idle:.0f} ({idle / (a.cores * span):.1%} of {a.cores} x {span:.0f} s)")
    if a.png:
        samples = None
        if a.samples:
            import pandas as pd

            d = pd.read_csv(a.samples, sep="\t")
            samples = (d["t_s"].tolist(), d["load1"].tolist())
        draw(js, stage_of, a.cores, a.png, samples)
        print(f"wrote {a.png}")


if __name__ == "__main__":
    main()

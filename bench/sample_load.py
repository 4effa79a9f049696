"""Sample a running workflow every few seconds: the Snakemake scheduler's own CPU time (its jobs
excluded), the load average and how many job processes run. For bench/timeline.py --samples.

    python bench/sample_load.py OUT.tsv [--match "snakemake --cores 2 all"] [--every 5]

Waits for a process whose command line contains --match, then writes t_s, main_cpu_s, load1 and
children every --every seconds until it exits.
"""

from __future__ import annotations

import argparse
import os
import time

import psutil


def find(match: str) -> psutil.Process:
    while True:
        for p in psutil.process_iter(["cmdline"]):
            if match in " ".join(p.info["cmdline"] or []) and p.pid != os.getpid():
                return p
        time.sleep(0.5)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--match", default="snakemake --cores 2 all")
    ap.add_argument("--every", type=float, default=5.0)
    a = ap.parse_args(argv)
    p = find(a.match)
    t0 = time.time()
    with open(a.out, "w") as f:
        f.write("t_s\tmain_cpu_s\tload1\tchildren\n")
        while True:
            try:
                c, kids = p.cpu_times(), p.children(recursive=True)
            except psutil.NoSuchProcess:
                break
            f.write(f"{time.time() - t0:.1f}\t{c.user + c.system:.2f}\t{os.getloadavg()[0]:.2f}\t{len(kids)}\n")
            f.flush()
            time.sleep(a.every)


if __name__ == "__main__":
    main()

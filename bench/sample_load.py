"""Sample a running workflow every few seconds: the Snakemake scheduler's own CPU time (its jobs
excluded), the load average and how many job processes run. For bench/timeline.py --samples.

    python bench/sample_load.py OUT.tsv [--match "snakemake --cores 2 all" | --pid PID] [--every 5] [--gpu]

Waits for a process whose command line contains --match (or takes process --pid), then writes
t_s, main_cpu_s, load1 and children every --every seconds until it exits; --gpu adds GPU 0's busy %
and memory in use (NVML, nvidia-ml-py), as NVML averages them over its last sample period.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import psutil


def find(match: str) -> psutil.Process:
    while True:
        for p in psutil.process_iter(["cmdline"]):
            if match in " ".join(p.info["cmdline"] or []) and p.pid != os.getpid():
                return p
        time.sleep(0.5)


def nvml():
    """A reader of GPU 0's (busy %, MiB in use); None, with a line on stderr, where NVML is not."""
    try:
        import pynvml

        pynvml.nvmlInit()
        h = pynvml.nvmlDeviceGetHandleByIndex(0)
    except Exception as e:  # noqa: BLE001 -- no driver, no GPU or no nvidia-ml-py: no GPU columns
        print(f"sample_load: no GPU columns ({type(e).__name__}: {e})", file=sys.stderr)
        return None
    return lambda: (pynvml.nvmlDeviceGetUtilizationRates(h).gpu, pynvml.nvmlDeviceGetMemoryInfo(h).used / 2**20)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--match", default="snakemake --cores 2 all")
    ap.add_argument("--pid", type=int, help="sample this process (instead of --match)")
    ap.add_argument("--every", type=float, default=5.0)
    ap.add_argument("--gpu", action="store_true", help="add gpu_util (%%) and gpu_mem_mib of GPU 0")
    a = ap.parse_args(argv)
    gpu = nvml() if a.gpu else None
    p = psutil.Process(a.pid) if a.pid else find(a.match)
    t0 = time.time()
    with open(a.out, "w") as f:
        f.write("t_s\tmain_cpu_s\tload1\tchildren" + ("\tgpu_util\tgpu_mem_mib" if gpu else "") + "\n")
        while True:
            try:
                c, kids = p.cpu_times(), p.children(recursive=True)
            except psutil.NoSuchProcess:
                break
            row = f"{time.time() - t0:.1f}\t{c.user + c.system:.2f}\t{os.getloadavg()[0]:.2f}\t{len(kids)}"
            f.write(row + ("\t{}\t{:.0f}".format(*gpu()) if gpu else "") + "\n")
            f.flush()
            time.sleep(a.every)


if __name__ == "__main__":
    main()

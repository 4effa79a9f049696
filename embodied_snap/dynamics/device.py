"""Where the GRU runs: config `dynamics.device` (training) and `policy.device` (the searches'
rollouts), each auto, cpu or cuda; auto takes the GPU where one is visible, cuda falls back to CPU
with one log line where none is.

On a cluster a job asks for a GPU only when the config says cuda (resources gpu: auto is decided
on the node the job lands on, so a cluster config names cuda). CPU and GPU results agree to
float32 rounding, not bit for bit; each is deterministic on its own device (docs/cluster.md).
"""

from __future__ import annotations

import os
import sys

import torch

DEVICES = ("auto", "cpu", "cuda")


def resolve(wanted: str, log=None, key: str = "dynamics.device") -> str:
    """The torch device for config value `wanted` (of config `key`); "cuda" without a visible GPU
    falls back to "cpu" with one line through `log` (default: stderr, the job's log)."""
    if wanted not in DEVICES:
        raise ValueError(f"{key}: {wanted!r} is not one of {', '.join(DEVICES)}")
    gpu = torch.cuda.is_available()
    if wanted == "cuda" and not gpu:
        say = log or (lambda m: print(m, file=sys.stderr, flush=True))
        say(f"{key} is cuda but no GPU is visible: running on cpu")
        return "cpu"
    if wanted == "cpu" or not gpu:
        return "cpu"
    # cuBLAS is deterministic only with a fixed workspace; set before its first call.
    os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch.use_deterministic_algorithms(True)
    return "cuda"

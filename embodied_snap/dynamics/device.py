"""Where the GRU runs: config `dynamics.device` (cpu or cuda), on CPU when no GPU is visible.

On a cluster the training job asks for a GPU only when the config says cuda (rules/dynamics.smk,
resources gpu); a job that got none, or a machine without one, still runs, on CPU, and says so in
one log line. CPU and GPU results agree to float32 rounding, not bit for bit (docs/cluster.md).
"""

from __future__ import annotations

import os
import sys

import torch

DEVICES = ("cpu", "cuda")


def resolve(wanted: str, log=None) -> str:
    """The torch device for config value `wanted`; "cuda" without a visible GPU falls back to
    "cpu" with one line through `log` (default: stderr, the job's log)."""
    if wanted not in DEVICES:
        raise ValueError(f"dynamics.device: {wanted!r} is not one of {', '.join(DEVICES)}")
    if wanted == "cuda" and not torch.cuda.is_available():
        (log or (lambda m: print(m, file=sys.stderr, flush=True)))(
            "dynamics.device is cuda but no GPU is visible: running on cpu")
        return "cpu"
    if wanted == "cuda":
        # cuBLAS is deterministic (torch.use_deterministic_algorithms) only with a fixed workspace.
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    return wanted

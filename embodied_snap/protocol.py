"""The experimental protocol, read once from the validated config.

Every number that the paper fixes and config.yaml carries (the mocap gap bridged, the window
lengths, the attachment threshold, the timing set and action ranges, the primitive's S2 ramp and
canonical bearing, the rig's rated servo speed and geometry) reaches code from here, as frozen
dataclasses, never as a module constant. Workflow rules pass `params(config, *sections)` to their
scripts as Snakemake params (so a changed value reruns exactly the jobs that use it) and the
scripts rebuild the dataclasses with `from_params`.

One number is no config value: the grid rate, GRID_HZ. The dynamics windows and the paper's report
horizons are counted in its steps, so no other rate could run; it still reaches the jobs through
the `sampling` section, like the values beside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType


@dataclass(frozen=True)
class Sampling:
    """The state/command grid (paper IV-A)."""

    hz: float  # GRID_HZ, the same for every config
    max_gap_s: float  # config resample.max_gap_s: the longest mocap dropout bridged

    @property
    def dt(self) -> float:
        # 1 / 50 is exactly the float 0.02 the pipeline always used.
        return 1 / self.hz


@dataclass(frozen=True)
class Windows:
    """Training windows of the dynamics model, in grid steps (paper IV-A)."""

    history: int
    lookahead: int
    horizon: int
    stride: int
    snap_speed_mps: float
    fast_speed_mps: float
    per_dynamics_group: int  # the acquisition records a dynamics group this long (paper IV-A)


def window_span(history: int, lookahead: int, horizon: int) -> tuple[int, int]:
    """Rows needed before and after an anchor: x/u history back, targets and rollout commands on."""
    return history - 1, max(horizon, horizon - 1 + lookahead)


@dataclass(frozen=True)
class Primitive:
    """The snap primitive's fixed parts (paper III-B, IV-C) and its commanded ranges (Eq. 7-8)."""

    phi0_deg: float  # the canonical bearing the primitive is validated around
    s2_ramp_s: float  # S2 is released over this long
    ranges: MappingProxyType  # action -> (low, high); tau's range is the timing set T of Eq. 8

    @property
    def timing_s(self) -> tuple[float, float]:
        return tuple(self.ranges["tau"])


@dataclass(frozen=True)
class Rig:
    """What the recordings cannot give: the servos' datasheet speed and the arm's geometry."""

    rated_speed_tick_s: float
    tendon_radius_m: tuple
    end_effector_m: float
    arm_length_m: float  # S1+S2+S3 undeformed, without the end effector


@dataclass(frozen=True)
class Thresholds:
    attach_speed_mps: float  # the empirical attachment threshold (paper III-A)


@dataclass(frozen=True)
class Protocol:
    """The sections a job asked for; the others are None."""

    sampling: Sampling | None = None
    windows: Windows | None = None
    primitive: Primitive | None = None
    rig: Rig | None = None
    thresholds: Thresholds | None = None


# What the acquisition's programs read (the simulated rig's, esnap lab's plan, esnap twin acquire).
ACQUISITION = ("sampling", "windows", "primitive", "rig", "thresholds")

_CLASSES = {"sampling": Sampling, "windows": Windows, "primitive": Primitive, "rig": Rig,
            "thresholds": Thresholds}


# The state/command grid (paper IV-A: 50 Hz): the dynamics windows (history, lookahead, horizon) and
# the report horizons (0.3/0.5/0.7 s) are defined in its steps. An int, as config.yaml once spelled
# it, so the `sampling` param and the results that carry it keep their bytes.
GRID_HZ = 50


def _section(config: dict, name: str) -> dict:
    """Plain values of one section, straight from the (validated) config. Numbers that land in
    results as JSON are floats, however the YAML spells them (210 and 210.0 write differently)."""
    if name == "sampling":
        return dict(hz=GRID_HZ, max_gap_s=config["resample"]["max_gap_s"])
    if name == "windows":
        return dict(config["windows"])
    if name == "primitive":
        p = config["primitive"]
        return dict(phi0_deg=float(p["phi0_deg"]), s2_ramp_s=float(p["s2_ramp_s"]),
                    ranges={k: list(v) for k, v in config["policy"]["ranges"].items()})
    if name == "rig":
        r = config["rig"]
        return dict(rated_speed_tick_s=float(r["rated_speed_tick_s"]), tendon_radius_m=list(r["tendon_radius_m"]),
                    end_effector_m=r["end_effector_m"], arm_length_m=float(r["arm_length_m"]))
    if name == "thresholds":
        return dict(attach_speed_mps=config["characterize"]["attach_speed_mps"])
    raise KeyError(f"no protocol section {name!r}; known: {', '.join(_CLASSES)}")


def params(config: dict, *sections: str) -> dict:
    """The named sections as plain dicts and lists: a Snakemake param (all sections if none named)."""
    return {s: _section(config, s) for s in (sections or _CLASSES)}


def from_params(p: dict) -> Protocol:
    """The dataclasses back from `params` (lists become tuples and dicts read-only mappings, so the
    objects stay immutable)."""
    def freeze(v):
        if isinstance(v, dict):
            return MappingProxyType({k: freeze(x) for k, x in v.items()})
        return tuple(freeze(x) for x in v) if isinstance(v, (list, tuple)) else v

    return Protocol(**{s: _CLASSES[s](**{k: freeze(v) for k, v in d.items()}) for s, d in p.items()})


def load(config: dict) -> Protocol:
    """The whole protocol of a config."""
    return from_params(params(config))


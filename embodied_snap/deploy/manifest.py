"""The deployment manifest (paper VI; docs/deployment.md): everything `esnap deploy` reads.

`build` (run by the workflow, rule deploy_manifest) gathers the selected shared policy (weights,
input normalisation), the action ranges and timing set, the directional workspace, the canonical
bearing constants, the servo ids and goal map, the calibration, the hardware envelope, the six
placements, the code version and the sha256 of every input. `checksum` covers all of it; `load`
refuses a manifest whose checksum fails. Standard library and numpy only.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from .. import bearing as BR
from ..files import sha256
from ..policy import geometry
from ..primitive import ANTAGONIST_FACTOR, CABLE_BEARINGS_DEG, section_goals
from . import controltable as CT

FORMAT = "esnap-deployment-manifest/1"
SERVO_IDS = list(range(1, 10))


class ManifestError(ValueError):
    """The manifest cannot be used: one line naming the file and what is wrong."""


def checksum(body: dict) -> str:
    """sha256 of the canonical JSON of everything but the checksum itself."""
    b = {k: v for k, v in body.items() if k != "checksum"}
    return hashlib.sha256(json.dumps(b, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def load(path) -> dict:
    """The manifest at `path`, its checksum verified."""
    try:
        with open(path) as f:
            man = json.load(f)
    except (OSError, ValueError) as e:
        raise ManifestError(f"{path}: cannot read the manifest ({e})") from None
    if not isinstance(man, dict) or man.get("format") != FORMAT:
        raise ManifestError(f"{path}: not a deployment manifest (format {FORMAT} expected)")
    if man.get("checksum") != checksum(man):
        raise ManifestError(f"{path}: manifest checksum mismatch: it was changed after export "
                            f"(recorded {str(man.get('checksum'))[:12]}, content {checksum(man)[:12]})")
    return man


def reach(rho_max, s3_max: float, carry_ticks: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-servo lowest and highest goal the goal map gives for any preload up to `rho_max` (rows of
    the three sections' preloads, e.g. the directional workspace's largest per bin), at every bearing,
    with or without the full S3 slack, plus the carry; rest (0) included."""
    bear = np.arange(0.0, 360.0, 1.0)
    G = [np.zeros(9)]
    for rho in np.asarray(rho_max, float):
        for b in bear:
            w = section_goals(rho, b)
            G += [w, w - np.r_[np.zeros(6), np.full(3, s3_max)]]
    g = np.asarray(G)
    carry = np.tile(carry_ticks * np.cos(np.deg2rad(bear[:, None] - np.array(CABLE_BEARINGS_DEG))), 3)
    return g.min(0) + np.minimum(carry.min(0), 0), g.max(0) + np.maximum(carry.max(0), 0)


def arm_limits(ranges: dict, carry_ticks: float, margin: float) -> dict:
    """The servos' EEPROM position limits, one pair per servo for every program the arm runs (the
    acquisition plan's and the deployment manifest's): the reach of the largest preloads and S3
    slack the action ranges allow (policy.ranges, which bound every drawn program and the recorded
    workspace), plus the carry, widened by `margin` of each servo's span and rounded outward."""
    rho = [[ranges[k][1] for k in ("rho1", "rho2", "rho3")]]
    lo, hi = reach(rho, ranges["s3"][1], carry_ticks)
    pad = margin * (hi - lo)
    return dict(eeprom_min=np.floor(lo - pad).astype(int).tolist(), eeprom_max=np.ceil(hi + pad).astype(int).tolist())


def envelope(rho_max, s3_max: float, carry_ticks: float, margin: float, limits: dict) -> dict:
    """Per-servo goal limits: every goal the goal map gives for any recorded preload (the directional
    workspace's largest preload per bin), `reach`, widened by `margin` of each servo's span; the
    EEPROM limits are the arm's (`arm_limits`)."""
    return widened(*reach(rho_max, s3_max, carry_ticks), margin, limits)


def widened(lo, hi, margin: float, limits: dict) -> dict:
    """Per-servo goal limits lo .. hi widened by `margin` of each servo's span, with the arm's EEPROM
    limits (the manifest's envelope, esnap lab's plan). Refuses goal limits the EEPROM limits do not
    hold: the same arm runs every plan and manifest of its config without rewriting them."""
    pad = margin * (hi - lo)
    lo, hi = np.round(lo - pad, 1), np.round(hi + pad, 1)
    out = dict(margin_fraction=margin, goal_min=lo.tolist(), goal_max=hi.tolist(), **limits)
    bad = np.flatnonzero((lo < out["eeprom_min"]) | (hi > out["eeprom_max"]))
    if len(bad):
        j = int(bad[0])
        raise ValueError(f"servo {j + 1}: goals {lo[j]:.0f} .. {hi[j]:.0f} outside the arm's EEPROM limits "
                         f"{out['eeprom_min'][j]} .. {out['eeprom_max'][j]} (config policy.ranges, "
                         "deployment.schedule.carry_ticks)")
    return out


def start(cfg: dict, rated_speed_tick_s: float) -> dict:
    """How a program starts where the arm is (config deployment.start; docs/deployment.md, "Where the
    arm starts"): the tolerance outside the EEPROM limits, the ramp's speed (a share of the rated
    speed, tick/s) and its current limit (mA)."""
    st = cfg["start"]
    return dict(tolerance_ticks=int(st["tolerance_ticks"]),
                ramp_tick_s=round(st["speed_fraction"] * rated_speed_tick_s, 3), current_ma=float(st["current_ma"]))


def feature_box(ws: dict, pad_m: float) -> dict:
    """Where a target may lie: the strike cloud's features g = (d, e, r) in the canonical frame
    (Eq. 5), widened by pad_m. Targets outside were never reached on the rig."""
    n = np.asarray(ws["hanging_axis"], float)
    g = geometry.features(np.asarray(ws["strike_points_m"], float), n)
    return dict(lo=(g.min(0) - pad_m).round(5).tolist(), hi=(g.max(0) + pad_m).round(5).tolist(), pad_m=pad_m)


def placements(ws: dict, distances_m, bearing_range_deg: float, n: int, box: dict | None = None) -> list[dict]:
    """n target placements at distances spread over distances_m and bearings over bearing_range_deg
    centred on the canonical strike bearing. A placement's distance is horizontal, from the hanging
    axis (the radius r of Eq. 5, what the lab measures on the table). For each: the recorded strike
    point whose r is nearest, its horizontal radius set to the distance (elevation kept), turned
    about the hanging axis to the bearing, its face normal against the recorded direction of travel
    (as the operator places the block). With `box` (feature_box), only strike points whose placed
    target stays inside the box are candidates, so that no placement is refused by its own manifest."""
    ax = np.asarray(ws["hanging_axis"], float)
    ax = ax / np.linalg.norm(ax)
    P, D = np.asarray(ws["strike_points_m"], float), np.asarray(ws["strike_dirs"], float)
    centre = ws["phi0_deg"] + ws["delta_str_deg"]
    dist = np.linspace(*distances_m, n)
    bear = centre + np.linspace(-bearing_range_deg / 2, bearing_range_deg / 2, n)
    _, e, r = geometry.features(P, ax).T
    out = []
    for i in range(n):
        cost = np.abs(r - dist[i])
        if box is not None:  # the placed target's (d, e, r): elevation kept, radius set to the distance
            g = np.stack([np.hypot(e, dist[i]), e, np.full_like(e, dist[i])], 1)
            inside = np.all((g > np.asarray(box["lo"]) + 1e-4) & (g < np.asarray(box["hi"]) - 1e-4), axis=1)
            cost = np.where(inside, cost, np.inf) if inside.any() else cost
        k = int(np.argmin(cost))
        along = (P[k] @ ax) * ax
        p = along + (P[k] - along) * dist[i] / r[k]
        turn = bear[i] - float(BR.bearing_deg(p, ax))
        p = BR.rotate(p, turn, ax)
        nrm = BR.rotate(-D[k], turn, ax)
        out.append(dict(placement=i + 1, distance_m=round(float(dist[i]), 4),
                        bearing_deg=round(float(bear[i]) % 360, 3), target_m=np.round(p, 5).tolist(),
                        normal=np.round(nrm / np.linalg.norm(nrm), 5).tolist()))
    return out


def build(inputs: dict, run: dict, workspace: dict, servo_fit: dict, cfg: dict, proto: dict, code_version: dict,
          lineage: dict) -> dict:
    """The manifest. inputs: name -> path (hashed); run: the selected shared policy's search run;
    servo_fit: results/characterize/servo.json; cfg: config `deployment`; proto: protocol params
    (primitive, rig); lineage: what fed the policy."""
    pol, prim, rig = cfg["policy"], proto["primitive"], proto["rig"]
    ranges = prim["ranges"]
    sch = cfg["schedule"]
    ws_keys = ("bin_lo_deg", "bin_width_deg", "rho_max", "phi0_deg", "delta_str_deg", "hanging_axis", "n_strikes")
    box = feature_box(workspace, cfg["target_pad_m"])
    try:
        env = envelope(workspace["rho_max"], ranges["s3"][1], sch["carry_ticks"], cfg["envelope_margin"],
                       arm_limits(ranges, sch["carry_ticks"], cfg["envelope_margin"]))
    except ValueError as e:
        raise ManifestError(f"the manifest's envelope: {e}") from None
    man = dict(
        format=FORMAT,
        code_version=code_version,
        policy=dict(arch=run["arch"], seed=run["seed"], n_params=run["n_params"], theta=run["theta"],
                    norm=run["norm"], selection_reward=run["selection_reward"],
                    selected_generation=run["selected_generation"]),
        actions=dict(ranges=ranges, timing_s=list(ranges["tau"]), workspace_fraction=pol["workspace_fraction"]),
        workspace={k: workspace[k] for k in ws_keys},
        target_box=box,
        primitive=dict(phi0_deg=prim["phi0_deg"], s2_ramp_s=prim["s2_ramp_s"],
                       cable_bearings_deg=list(CABLE_BEARINGS_DEG), antagonist_factor=ANTAGONIST_FACTOR,
                       end_effector_m=rig["end_effector_m"], schedule=dict(sch)),
        servos=dict(ids=SERVO_IDS, model_number=CT.XM430_W350, operating_mode=CT.EXTENDED_POSITION_MODE,
                    goal_map="servo 3(s-1)+k pulls tendon k (azimuth 120(k-1) deg) of section s; goals in ticks "
                             "from the straight hanging arm (Homing Offset sets rest = 0)",
                    baud=cfg["baud"], hz=cfg["servo_hz"], watchdog_ms=cfg["watchdog_ms"],
                    reply_timeout_ms=cfg["reply_timeout_ms"], reply_retries=cfg["reply_retries"],
                    start=start(cfg, rig["rated_speed_tick_s"])),
        calibration=dict(lever_ticks_per_rad=servo_fit["lever_ticks_per_rad"],
                         ceiling_rad_s=servo_fit["ceiling_rad_s"], rated_speed_tick_s=rig["rated_speed_tick_s"]),
        envelope=env,
        placements=placements(workspace, cfg["distances_m"], cfg["bearing_range_deg"], cfg["n_placements"], box),
        inputs={k: dict(path=str(p), sha256=sha256(p)) for k, p in sorted(inputs.items())},
        lineage=lineage,
    )
    man["checksum"] = checksum(man)
    return man


def inputs_changed(man: dict, root=".") -> list[str]:
    """Inputs of the manifest whose file changed (or vanished) since export: one line each."""
    out = []
    for k, e in man["inputs"].items():
        p = Path(root) / e["path"]
        if not p.exists():
            out.append(f"{e['path']} ({k}) is gone since the manifest was exported")
        elif sha256(p) != e["sha256"]:
            out.append(f"{e['path']} ({k}) changed after the manifest was exported")
    return out

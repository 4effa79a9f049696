"""`esnap lab plan`: the sessions a lab records, in the order an operator works.

The plan is the acquisition protocol (embodied_snap.acquisition) written out for one budget: every
group of the budget (ids and sessions as the workflow numbers them, embodied_snap.plan.twin_plan),
its drawn program, what the operator does for it and which labels they will be asked for, plus the
bus settings and the goal envelope every program stays inside (the EEPROM limits the servos must
carry). A checksum covers all of it; `load` refuses a plan that was edited after it was written,
so the group a lab records is the group the plan drew.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import yaml

from ..acquisition import draws as D
from ..capture.importer import MEASURED_LABELS
from ..deploy import controltable as CT
from ..deploy.manifest import SERVO_IDS, arm_limits, start, widened
from ..files import write_text
from ..plan import twin_plan
from ..protocol import ACQUISITION, from_params, params
from ..rawformat import CATEGORIES, EVIDENCE_SETS

FORMAT = "esnap-lab-plan/1"
PROTOCOL_FILES = ("draws.py", "programs.py")  # what the protocol's version hashes


class PlanError(ValueError):
    """One line: the plan file and what is wrong with it."""


def protocol_version() -> str:
    """sha256 (12 hex) of the acquisition protocol's code: a plan drawn by other programs or draws is
    not this protocol (a new package version with the same protocol keeps its plans)."""
    h = hashlib.sha256()
    for name in PROTOCOL_FILES:
        h.update((Path(D.__file__).parent / name).read_bytes())
    return h.hexdigest()[:12]


def checksum(body: dict) -> str:
    b = {k: v for k, v in body.items() if k != "checksum"}
    return hashlib.sha256(json.dumps(b, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def goals_sha256(goals: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(goals, dtype="<i8").tobytes()).hexdigest()


def drawn(row: dict, seed: int, proto, hz: float):
    """(program, target offset, goal trace at the bus rate as the servos take it (integer ticks,
    frozen), phase times, held-base cue) of one group."""
    _, prog, off, goals, times, cue = D.draw_group(row, seed, proto, 1.0 / hz)
    g = np.rint(goals).astype(np.int64)
    g.setflags(write=False)
    return prog, off, g, times, cue


def labels_asked(config: dict, es: str, cat: str, times: dict, cue: float | None) -> list[str]:
    """The labels a set needs (gate.labels) that nothing measures: not a phase time of the program,
    not the held-base cue the client logs, not what the importer computes."""
    need = config["gate"]["labels"].get(f"{es}/{cat}", config["gate"]["labels"].get(es, []))
    logged = set(times) | ({"base_event_t"} if cue is not None else set()) | set(MEASURED_LABELS)
    return [k for k in need if k not in logged]


def operator_step(es: str, cat: str, target: dict | None, cue: float | None) -> str:
    if target is not None:
        x, y, z = (1000 * v for v in target["centre_m"])
        return (f"place the {'x'.join(f'{1000 * s:g}' for s in target['size_m'])} mm block, struck face toward "
                f"the arm, its centre at x {x:.0f}, y {y:.0f}, z {z:.0f} mm from the mount (arm frame); "
                "the capture records where it really stands")
    if cue is not None:
        return f"hold the mount and push it when the cue sounds ({cue:.2f} s into the program)"
    return "nothing: keep clear of the arm"


def _order(row: dict) -> tuple:
    """Sessions in turn; within one, one evidence set (and category) at a time."""
    es = row["evidence_set"]
    return (row["session"], EVIDENCE_SETS.index(es), CATEGORIES[es].index(row["category"]), row["group_id"])


def envelope(goals: list[np.ndarray], margin: float, limits: dict) -> dict:
    """Per-servo goal limits: every goal the plan commands, widened by `margin` of each servo's span
    (as the deployment manifest's envelope); the EEPROM limits are the arm's, the manifest's own
    (deploy.manifest.arm_limits): the arm set up for the plan runs the deployment unchanged."""
    g = np.vstack([np.zeros((1, 9))] + list(goals))
    return widened(g.min(0), g.max(0), margin, limits)


def build(config: dict, budget: str, place=None) -> dict:
    """The plan of `budget` (config budgets.<name>). `place(bearing, offset) -> {centre_m, quat, size_m}`
    suggests where a target stands (the CLI gives the simulated rig's nominal strike; None: no
    suggestion, the operator places it at the strike point and the capture measures it)."""
    dep = config["deployment"]
    proto = from_params(params(config, *ACQUISITION))
    groups = twin_plan(config["budgets"][budget]["groups"], config["sessions"]).to_dict("records")
    entries, traces = [], []
    for row in sorted(groups, key=_order):
        prog, off, goals, times, cue = drawn(row, config["seed"], proto, dep["servo_hz"])
        traces.append(goals)
        target = None
        if off is not None:
            target = dict(size_m=list(D.BLOCK_SIZE_M), face=D.BLOCK_FACE, offset_m=[round(float(v), 5) for v in off])
            if place is not None:
                target.update(place(prog["bearing"], off))
        e = dict(group_id=row["group_id"], evidence_set=row["evidence_set"], category=row["category"],
                 session=row["session"], program={k: (round(v, 4) if isinstance(v, float) else v)
                                                  for k, v in prog.items()},
                 phases={k: round(float(v), 4) for k, v in times.items()},
                 duration_s=round(len(goals) / dep["servo_hz"], 3), goals_sha256=goals_sha256(goals),
                 operator=operator_step(row["evidence_set"], row["category"], target if place else None, cue),
                 labels=labels_asked(config, row["evidence_set"], row["category"], times, cue))
        if target is not None:
            e["target"] = target
        if cue is not None:
            e["cue_s"] = cue
        entries.append(e)
    try:
        env = envelope(traces, dep["envelope_margin"],
                       arm_limits(config["policy"]["ranges"], dep["schedule"]["carry_ticks"], dep["envelope_margin"]))
    except ValueError as e:
        raise PlanError(f"the plan's goals: {e}") from None
    doc = dict(
        format=FORMAT, budget=budget, seed=int(config["seed"]), protocol_version=protocol_version(),
        protocol=params(config, *ACQUISITION),
        servos=dict(ids=SERVO_IDS, model_number=CT.XM430_W350, operating_mode=CT.EXTENDED_POSITION_MODE,
                    baud=dep["baud"], hz=dep["servo_hz"], watchdog_ms=dep["watchdog_ms"],
                    reply_timeout_ms=dep["reply_timeout_ms"], reply_retries=dep["reply_retries"],
                    start=start(dep, config["rig"]["rated_speed_tick_s"])),
        envelope=env,
        gate=dict(max_servo_gap_s=float(config["gate"]["max_servo_gap_s"])),  # checked as each log is recorded
        groups=entries,
    )
    doc["checksum"] = checksum(doc)
    return doc


def write(doc: dict, path) -> None:
    write_text(path,
        f"# esnap lab plan: {len(doc['groups'])} groups of the {doc['budget']} budget, in the order they are "
        "recorded.\n# Do not edit: the checksum covers every line (esnap lab acquire refuses an edited plan).\n"
        + yaml.safe_dump(doc, sort_keys=False, width=110, default_flow_style=None))


def load(path) -> dict:
    """The plan at `path`, its checksum and its protocol version verified."""
    try:
        doc = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as e:
        raise PlanError(f"{path}: cannot read the plan ({str(e).splitlines()[0]})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise PlanError(f"{path}: not an acquisition plan (format {FORMAT} expected; write one with esnap lab plan)")
    if doc.get("checksum") != checksum(doc):
        raise PlanError(f"{path}: plan checksum mismatch: it was changed after esnap lab plan wrote it")
    if doc["protocol_version"] != protocol_version():
        raise PlanError(f"{path}: drawn by protocol {doc['protocol_version']}, this is {protocol_version()}: "
                        "write the plan again (esnap lab plan)")
    return doc


def group_goals(doc: dict, entry: dict) -> tuple[np.ndarray, dict]:
    """The group's goal trace, drawn again from the plan's seed and protocol and checked against the
    plan's checksum of it."""
    proto = from_params(doc["protocol"])
    row = {k: entry[k] for k in ("group_id", "evidence_set", "category", "session")}
    _, _, goals, times, _ = drawn(row, doc["seed"], proto, doc["servos"]["hz"])
    if goals_sha256(goals) != entry["goals_sha256"]:
        raise PlanError(f"group {entry['group_id']}: its goals drawn again differ from the plan's")
    return goals, times


def summary(doc: dict) -> str:
    """A line per evidence set (its groups, minutes of program, the operator's part), then a line
    per session: its sets, groups and minutes of program."""
    out = []
    for es in EVIDENCE_SETS:
        g = [e for e in doc["groups"] if e["evidence_set"] == es]
        if g:
            mins = sum(e["duration_s"] for e in g) / 60
            n = {k: sum(k in e for e in g) for k in ("target", "cue_s")}
            does = ", ".join([f"places the block {n['target']}x"] * bool(n["target"])
                             + [f"pushes the mount {n['cue_s']}x"] * bool(n["cue_s"])) or "keeps clear"
            out.append(f"{es}: {len(g)} group{'s' * (len(g) != 1)}, {mins:.1f} min of programs; the operator {does}")
    sessions = sorted({e["session"] for e in doc["groups"]})
    for s in sessions:
        g = [e for e in doc["groups"] if e["session"] == s]
        sets = ", ".join(f"{es} {sum(e['evidence_set'] == es for e in g)}" for es in EVIDENCE_SETS
                         if any(e["evidence_set"] == es for e in g))
        mins = sum(e["duration_s"] for e in g) / 60
        out.append(f"{s}: {len(g)} group{'s' * (len(g) != 1)} ({sets}), {mins:.1f} min of programs")
    return "\n".join(out)

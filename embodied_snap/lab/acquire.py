"""`esnap lab acquire`: a plan's groups recorded on the arm, one at a time, as the operator works.

Each group: the operator's step is shown and confirmed, the group's program (drawn again from the
plan and checked against it) is played through esnap deploy's own client and preflight (model
number, operating mode, EEPROM limits, where the arm rests and the ramp from there to the first
goal, watchdog, torque off whatever happens), and the servo log and meta.json are written into the
session folder as a group folder `esnap import` completes with the capture system's take of the
same name. Every argument and every group's goals are checked before the port opens. A recorded
group is never written again; an aborted one (Ctrl-C, a servo fault, a lost port) stops the session
with one line and leaves `aborted/<group_id>.json` until it is recorded, and the next run resumes
at the first group without a servo log (of one session or evidence set, when narrowed to it).

The session folder:

    <out>/groups/<group_id>/servo.parquet, meta.json   what the servo PC ran and logged
    <out>/aborted/<group_id>.json                      why a group stopped
    <out>/<session>.yaml                               esnap import's session file (captures: takes)
    <out>/takes/                                       where the capture system's takes go, named by group id
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .. import rawformat as RF
from ..deploy import client
from ..deploy.commands import RefusedTarget, check_envelope
from ..files import write_text
from ..rawformat import RecordingError
from ..validate import check_servo_gaps
from .plan import PlanError, group_goals, load

CAPTURES = "takes"  # the session folder's folder for the capture system's takes
MAX_ATTEMPTS = 3  # a group whose servo log the gate refuses this often in a row stops the session


class LabError(ValueError):
    """One line: what was refused before the arm moved, or why a session stopped."""


class LabArgumentError(LabError):
    """A bad command-line argument (--from, --session, --evidence-set, --baud, --out)."""


def recorded(out: Path, gid: str) -> bool:
    d = Path(out) / "groups" / gid
    return (d / "servo.parquet").is_file() and (d / "meta.json").is_file()


def narrowed(doc: dict, plan_path, session: str | None, evidence_set: str | None) -> list[dict]:
    """The plan's groups of one session and/or one evidence set (None: all), in the plan's order."""
    groups = doc["groups"]
    for flag, key, want in (("--session", "session", session), ("--evidence-set", "evidence_set", evidence_set)):
        if want is None:
            continue
        there = sorted({e[key] for e in groups})
        if want not in there:
            raise LabArgumentError(f"{flag} {want}: not a{'n' * (key == 'evidence_set')} {key.replace('_', ' ')} of "
                                   f"{plan_path}{' in ' + session if key == 'evidence_set' and session else ''} "
                                   f"({', '.join(there)})")
        groups = [e for e in groups if e[key] == want]
    return groups


def checked(plan_path, out, start: str | None, baud: int | None, session: str | None = None,
            evidence_set: str | None = None):
    """(plan, its groups from the first to record, goals per group id, baud): everything refused
    here, before any port opens. `session`, `evidence_set`: only that session's (set's) groups."""
    try:
        doc = load(plan_path)
    except PlanError as e:
        raise LabError(str(e)) from None
    try:
        client.checked_start(doc)
    except client.ArgumentError as e:
        raise LabError(f"{plan_path}: {e}") from None
    try:
        client.checked_servo_ids(doc)
        baud = client.checked_baud(doc, baud)
    except client.ArgumentError as e:
        raise LabArgumentError(str(e)) from None
    groups = narrowed(doc, plan_path, session, evidence_set)
    ids = [e["group_id"] for e in groups]
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise LabArgumentError(f"--out {out}: not a folder")
    if start is not None:
        if start not in ids:
            where = " and ".join(f"{k} {v}" for k, v in (("session", session), ("evidence set", evidence_set)) if v)
            raise LabArgumentError(f"--from {start}: not a group of {plan_path}{' in ' + where if where else ''} "
                                   f"({ids[0]} .. {ids[-1]})")
        if recorded(out, start):
            raise LabArgumentError(f"--from {start}: already recorded in {out}/groups/{start} (a recorded group is "
                                   "never overwritten: move its folder away to record it again)")
    first = ids.index(start) if start is not None else 0
    todo = [e for e in groups[first:] if not recorded(out, e["group_id"])]
    goals = {}
    for e in todo:
        try:
            g, _ = group_goals(doc, e)
            check_envelope(doc, g)
        except (PlanError, RefusedTarget) as err:
            raise LabError(f"{plan_path}: group {e['group_id']}: {err}") from None
        goals[e["group_id"]] = g
    return doc, todo, goals, baud


def cue_cycle(entry: dict, hz: float) -> int | None:
    """The bus cycle on which the held-base cue sounds (None: no cue)."""
    return None if "cue_s" not in entry else int(np.ceil(entry["cue_s"] * hz - 1e-9))


def group_meta(doc: dict, entry: dict, log: np.ndarray, k_cue: int | None, start: dict | None = None) -> dict:
    """meta.json of a recorded group; `start`: where the arm started and its ramp (client.start_ramp)."""
    meta = dict(format_version=RF.FORMAT_VERSION, group_id=entry["group_id"], evidence_set=entry["evidence_set"],
                category=entry["category"], session=entry["session"],
                recorded_at=_dt.datetime.now().isoformat(timespec="seconds"), source="rig",
                goal_timing=client.LOG_GOAL_TIMING, program=entry["program"], labels=dict(entry["phases"]), events={},
                plan_sha256=doc["checksum"], protocol_version=doc["protocol_version"],
                **({"start": start} if start is not None else {}))
    if k_cue is not None:  # when the cue sounded, on the servo log's clock
        meta["events"]["base_event_t"] = round(float(log[min(k_cue, len(log) - 1), 0]), 4)
    if "target" in entry:
        meta["target"] = dict(size_m=entry["target"]["size_m"], face=entry["target"]["face"])
    return meta


def ask_labels(entry: dict, ask) -> dict:
    """The operator's outcome labels (y/n; Enter leaves it for the session's label sheet)."""
    out = {}
    for k in entry["labels"]:
        while True:
            a = ask(f"{entry['group_id']}: {k}? [y/n, Enter: later, on the label sheet] ").strip().lower()
            if a in ("y", "n", ""):
                break
        if a:
            out[k] = a == "y"
    return out


def write_session_files(doc: dict, out: Path) -> list[Path]:
    """One session file per session with recorded groups: esnap import's, the takes matched by name,
    and the label sheet `<session>_labels.csv` when the session folder has one."""
    files = []
    for s in sorted({e["session"] for e in doc["groups"]}):
        takes = [dict(servo=f"groups/{e['group_id']}") for e in doc["groups"]
                 if e["session"] == s and recorded(out, e["group_id"])]
        if takes:
            p = out / f"{s}.yaml"
            sheet = f"{s}_labels.csv"  # the operator's sheet, where labels were left for later
            doc_s = dict(session=s, **({"labels": sheet} if (out / sheet).is_file() else {}), captures=CAPTURES,
                         takes=takes)
            write_text(p, yaml.safe_dump(doc_s, sort_keys=False))
            files.append(p)
    return files


@dataclass(frozen=True)
class AcquireOptions:
    """esnap lab acquire's options: which of the plan's groups to record, and how."""

    start: str | None = None  # --from: the first group to record (default: the first not recorded)
    session: str | None = None  # --session: only that session's groups
    evidence_set: str | None = None  # --evidence-set: only that evidence set's groups
    baud: int | None = None  # --baud: the bus's baud rate (default: the plan's)
    yes: bool = False  # --yes: run every group without asking the operator (no labels asked either)


def acquire(plan_path, port, out, *, options: AcquireOptions = AcquireOptions(), ask=input, say=print,
            rig=None) -> dict:
    """Record the plan's groups from `options.start` (default: the first not recorded), of one session
    and/or evidence set when given (the plan's order kept). `port`: the serial
    port; `rig(entry)`, if given, a context manager yielding the port of that group instead (the
    simulated rig's virtual bus). Returns {recorded: [...], skipped: [...]}; raises LabError (one
    line) when refused or aborted, after torque went off."""
    yes = options.yes
    doc, todo, goals, baud = checked(plan_path, out, options.start, options.baud, options.session,
                                     options.evidence_set)
    out = Path(out)
    (out / CAPTURES).mkdir(parents=True, exist_ok=True)
    hz = float(doc["servos"]["hz"])
    done, skipped = [], []
    say(f"{len(todo)} groups to record ({len(doc['groups']) - len(todo)} of {len(doc['groups'])} already in {out})")
    for n, entry in enumerate(todo, 1):
        gid = entry["group_id"]
        say(f"[{n}/{len(todo)}] {gid} ({entry['evidence_set']}/{entry['category']}, session {entry['session']}, "
            f"{entry['duration_s']:.1f} s): {entry['operator']}")
        if not yes:
            answer = ask("Enter: run it, s: skip, q: stop the session ").strip().lower()
            if answer == "q":
                break
            if answer == "s":
                skipped.append(gid)
                continue
        k_cue = cue_cycle(entry, hz)
        on_cycle = None
        if k_cue is not None:
            def on_cycle(k, t, k_cue=k_cue):
                if k == k_cue:
                    say("\a>>> PUSH THE MOUNT NOW")
        for attempt in range(1, MAX_ATTEMPTS + 1):
            ctx = rig(entry) if rig is not None else contextlib.nullcontext(port)
            with ctx as group_port:
                started = {}
                log, cause, failed = client.drive(doc, group_port, baud, goals[gid], on_cycle, started)
                if started.get("ramp_cycles"):
                    say(f"{gid}: {client.ramped(started)}")
                refused = None if cause is not None else log_refused(doc, log, out, gid)
                if cause is None:  # a log the gate will refuse is kept aside, and the group run again
                    where = out if refused is None else out / "rejected" / str(attempt)
                    client.write_trial(where, group_meta(doc, entry, log, k_cue, started), log)
            if cause is not None:
                client.write_aborted(out, gid, cause, failed, plan_sha256=doc["checksum"])
                write_session_files(doc, out)
                raise LabError(f"{gid}: {client.aborted_line(cause, failed)} (marked in {out}/aborted/{gid}.json; "
                               "run again to record it)")
            if refused is None:
                break
            say(f"{gid}: the gate would refuse this servo log ({refused}); kept in {out}/rejected/{attempt}/, "
                "run again" + ("" if yes else ": redo the operator's step"))
            if not yes and ask("Enter: run it again, q: stop the session ").strip().lower() == "q":
                return finish(doc, out, done, skipped, say)
        else:
            write_session_files(doc, out)
            raise LabError(f"{gid}: the gate refused its servo log {MAX_ATTEMPTS} times in a row ({refused}): the bus "
                           "cannot keep the sync-read rate (docs/lab.md, a busy PC)")
        labels = ask_labels(entry, ask) if entry["labels"] and not yes else {}
        if labels:
            meta_path = out / "groups" / gid / "meta.json"
            meta = json.loads(meta_path.read_text())
            meta["labels"].update(labels)
            client.write_meta(meta_path, meta)
        done.append(gid)
        write_session_files(doc, out)
    return finish(doc, out, done, skipped, say)


def finish(doc: dict, out: Path, done: list, skipped: list, say) -> dict:
    write_session_files(doc, out)
    left = [e["group_id"] for e in doc["groups"] if not recorded(out, e["group_id"])]
    say(f"recorded {len(done)} groups; {len(left)} of the plan still to record"
        + (f" (next: {left[0]})" if left else "; put the capture system's takes in "
           f"{out / CAPTURES} named by group id and run esnap import on each session file"))
    return dict(recorded=done, skipped=skipped, left=left)


def log_refused(doc: dict, log: np.ndarray, out: Path, gid: str) -> str | None:
    """The gate's servo-log rule a recorded log breaks (validate.check_servo_gaps, under the plan's
    gate.max_servo_gap_s), or None."""
    try:
        check_servo_gaps(log[:, 0], out / "groups" / gid / "servo.parquet", gid, doc["gate"]["max_servo_gap_s"])
    except RecordingError as e:
        return f"{e.what} (rule: {e.rule})"
    return None


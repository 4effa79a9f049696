"""A test helper: the lab of `esnap lab acquire` on the simulated rig. Each group's servos are the
virtual Protocol 2.0 bus of twin/labrig.py (the arm driven live, the held-base push at the cue), the
capture system's take of a completed group is exported as a Motive CSV named by its group id into
the session's takes/, and the operator's questions are answered here (tests/test_lab_acquire.py,
bench/lab_roundtrip.py)."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import yaml

from embodied_snap.io import read_parquet
from embodied_snap.lab import acquire as LA
from embodied_snap.lab import plan as LP
from embodied_snap.twin.labrig import LabRig, LabRigSetup

from labexport import write_motive_csv
from paper_protocol import CONFIG as CONFIG_PATH
from paper_protocol import HOLD, PROTO

CONFIG = yaml.safe_load(CONFIG_PATH.read_text())
SEED, DT = CONFIG["seed"], CONFIG["twin"]["dt"]
CAPTURE_HZ = 120  # the takes are exported at a lab's usual rate, in millimetres
# The plan's bus settings with a generous reply timeout and watchdog, as tests/test_deploy.py's: the
# client and the virtual bus share a loaded CI machine, which may not run the bus for 20 ms.
PLAN_CONFIG = dict(CONFIG, deployment=dict(CONFIG["deployment"], reply_timeout_ms=250, watchdog_ms=1000))


def servo_log_end(out: Path, gid: str) -> float | None:
    """The last servo-log time of a recorded group (None: not recorded)."""
    if not LA.recorded(out, gid):
        return None
    return float(read_parquet(Path(out) / "groups" / gid / "servo.parquet")["t"].iloc[-1])


class SimLab:
    """The operator and the rig: `rig(entry)` is the virtual bus of one group (with `faults` for the
    groups named there), its take exported into the session's takes/ when the group completed;
    `ask` answers the operator's questions (run every group of `sessions`, stop at another; the
    labels as the rig saw them)."""

    def __init__(self, plan: Path, out: Path, faults: dict | None = None, sessions=None,
                 stop_after: int | None = None, capture_hz: float = CAPTURE_HZ):
        self.capture_hz = capture_hz
        self.out, self.faults, self.sessions, self.stop_after = Path(out), dict(faults or {}), sessions, stop_after
        self.results: dict[str, dict] = {}
        self.current: dict | None = None
        self.ran: list[str] = []
        self.plan = Path(plan)
        self.doc = LP.load(plan)

    def say(self, line: str) -> None:
        for e in self.doc["groups"]:
            if line.startswith("[") and f"] {e['group_id']} (" in line:
                self.current = e

    def ask(self, question: str) -> str:
        e = self.current
        if question.startswith("Enter: run it"):
            other = self.sessions is not None and e["session"] not in self.sessions
            # stop_after counts groups recorded (a run the gate's servo-log rule refused is run again)
            done = {g for g in self.ran if LA.recorded(self.out, g)}
            enough = self.stop_after is not None and len(done) >= self.stop_after
            return "q" if other or enough else ""
        label = question.split(": ", 1)[1].split("?")[0]
        return "y" if self.results[e["group_id"]][label] else "n"

    @contextlib.contextmanager
    def rig(self, entry: dict):
        gid = entry["group_id"]
        group = dict({k: entry[k] for k in ("group_id", "evidence_set", "category", "session", "program")},
                     target_offset_m=entry.get("target", {}).get("offset_m"), cue_s=entry.get("cue_s"))
        env = self.doc["envelope"]
        setup = LabRigSetup(seed=SEED, dt=DT, hold=HOLD, proto=PROTO, eeprom_min=env["eeprom_min"],
                            eeprom_max=env["eeprom_max"])
        r = LabRig(group, setup, faults=self.faults.get(gid))
        self.ran.append(gid)
        with r as port:
            try:
                yield port
            finally:
                t_end = servo_log_end(self.out, gid)
                if t_end is None:  # aborted: the arm stays on the bus until its watchdog has had time to fire
                    time.sleep(self.doc["servos"]["watchdog_ms"] / 1000 + 0.1)
                res = r.finish(None if t_end is None else t_end + 0.005)
                self.results[gid] = res
                if t_end is not None:
                    write_motive_csv(res["mocap"], self.out / LA.CAPTURES / f"{gid}.csv", rate_hz=self.capture_hz,
                                     take_name=gid)

    def acquire(self, **kw) -> dict:
        return LA.acquire(self.plan, None, self.out, options=LA.AcquireOptions(yes=False, **kw), ask=self.ask,
                          say=self.say, rig=self.rig)

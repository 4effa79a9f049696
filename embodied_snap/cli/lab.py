"""The commands that run in the lab, on the arm: `lab plan` and `lab acquire` (the paper's
acquisition, docs/lab.md), `deploy` (one trial of the deployed policy, docs/deployment.md) and
`deploy-index` (the trials recorded, for Table II and Fig. 7)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .common import (
    UsageError,
    config_args,
    existing_dir,
    existing_file,
    given_path,
    load_config,
    made_dir,
    positive,
)


def add_lab(sub) -> None:
    lb = sub.add_parser("lab", help="the paper's acquisition on the lab's arm: plan the sessions, record them")
    lsub = lb.add_subparsers(dest="lab_cmd", required=True, metavar="ACTION")
    lp = lsub.add_parser("plan", help="the sessions to record for a budget, in the order an operator works")
    lp.add_argument("--budget", help="paper, quick or smoke (default: config.yaml's budget)")
    lp.add_argument("--out", required=True, help="the plan file to write (YAML)")
    lp.add_argument("--no-targets", action="store_true",
                    help="no suggested target positions (they come from the simulated rig's model of the arm)")
    lp.add_argument("--force", action="store_true", help="replace an existing plan file")
    config_args(lp, "default: config.yaml; its budgets, seed, deployment bus settings")
    lp.set_defaults(fn=cmd_lab_plan)
    la = lsub.add_parser("acquire", help="record the plan's groups on the arm, resuming at the first not recorded")
    la.add_argument("--plan", required=True, help="the plan file esnap lab plan wrote")
    la.add_argument("--port", required=True, help="serial port of the servo bus, e.g. /dev/ttyUSB0")
    la.add_argument("--out", required=True, help="the session folder (groups/, aborted/, takes/, <session>.yaml)")
    la.add_argument("--from", dest="from_group", metavar="GROUP", help="start at this group (never one recorded)")
    la.add_argument("--session", help="only this session's groups (one of the plan's, e.g. s01)")
    la.add_argument("--evidence-set", help="only this evidence set's groups (e.g. held_base)")
    la.add_argument("--baud", type=int, help="default: the plan's (1000000); one the XM430 supports")
    la.add_argument("--yes", action="store_true", help="do not wait for the operator before each group")
    la.set_defaults(fn=cmd_lab_acquire)


def add_deploy(sub) -> None:
    d = sub.add_parser("deploy", help="run one open-loop trial of the deployment manifest on the servos")
    d.add_argument("--manifest", default="results/deployment/manifest.json")
    d.add_argument("--port", help="serial port of the servo bus, e.g. /dev/ttyUSB0")
    d.add_argument("--baud", type=int, help="default: the manifest's (1000000); one the XM430 supports")
    tg = d.add_mutually_exclusive_group()
    tg.add_argument("--target", help="x,y,z of the target in the base frame (m); --target=-0.1,... when x < 0")
    tg.add_argument("--target-from-mocap", help="JSON file {target_m: [x, y, z]} exported by the mocap system")
    d.add_argument("--placement", type=int, metavar="K",
                   help="which of the manifest's placements (1-based) the block stands at: recorded for Table II, "
                        "and the target unless --target or --target-from-mocap gives the measured one")
    d.add_argument("--out", help="recording tree to write the trial into (groups/<id>/, aborted/)")
    d.add_argument("--group-id", default="dep_0001")
    d.add_argument("--dry-run", action="store_true", help="print the commands and goal schedule, open no port")
    d.add_argument("--yes", action="store_true", help="do not ask before moving the arm")
    d.set_defaults(fn=cmd_deploy)


def add_deploy_index(sub) -> None:
    di = sub.add_parser("deploy-index", help="index the deployment trials recorded in the lab (Table II, Fig. 7)")
    di.add_argument("--raw", help="the deployment recording tree (default: <raw_data.dir>/deployment)")
    config_args(di, "default: config.yaml; its gate and raw_data.dir")
    di.add_argument("--planned", type=positive, help="trials planned (default: those found); Table II's denominator")
    di.set_defaults(fn=cmd_deploy_index)


def cmd_lab_plan(a) -> int:
    """The sessions a lab records for a budget (docs/lab.md): the acquisition protocol's
    groups, programs and operator steps, the targets where the simulated rig's model of the arm
    says the cup strikes."""
    from ..lab import plan as LP
    from ..twin.acquire import place_target  # a suggestion for the operator; the capture measures it

    cfg = load_config(a)
    budget = a.budget or cfg["budget"]
    if budget not in cfg["budgets"]:
        raise UsageError(f"--budget {budget}: not a budget of the config ({', '.join(cfg['budgets'])})")
    out = given_path(a.out, "--out")
    if out.is_dir():
        raise UsageError(f"--out {out}: a directory; give the plan file to write")
    if out.exists() and not a.force:
        raise UsageError(f"--out {out}: exists (a plan being recorded is never rewritten; --force to replace it)")
    if not out.absolute().parent.is_dir():
        raise UsageError(f"--out {out}: {out.absolute().parent} is not a directory")
    proto = None
    if not a.no_targets:
        from .. import protocol

        proto = protocol.load(cfg)

    def place(bearing, offset):
        t = place_target(bearing, offset, float(cfg["twin"]["dt"]), proto)
        return dict(centre_m=[round(float(v), 4) for v in t["pos"]], quat=[round(float(v), 5) for v in t["quat"]])

    try:
        doc = LP.build(cfg, budget, place=None if a.no_targets else place)
    except LP.PlanError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    LP.write(doc, out)
    print(LP.summary(doc))
    env, ids = doc["envelope"], doc["servos"]["ids"]
    print(f"wrote {out}: {len(doc['groups'])} groups in {len({e['session'] for e in doc['groups']})} sessions, "
          f"{sum(e['duration_s'] for e in doc['groups']) / 60:.1f} min of programs; set the servos' EEPROM position "
          f"limits (ids {ids[0]}..{ids[-1]}) to min {env['eeprom_min']}, max {env['eeprom_max']}")
    return 0


def cmd_lab_acquire(a) -> int:
    """Record the plan's groups on the arm (docs/lab.md); every argument and every group's
    goals are checked before the port opens."""
    from ..lab.acquire import AcquireOptions, LabArgumentError, LabError, acquire

    existing_file(a.plan, "--plan")
    if not a.port or not a.port.strip():
        raise UsageError("--port: empty (the servo bus, e.g. /dev/ttyUSB0)")
    if not os.path.exists(a.port):
        raise UsageError(f"--port {a.port}: no such device")
    if not a.yes and not sys.stdin.isatty():
        raise UsageError("--yes is required when stdin is not a terminal: nobody can be asked before the arm moves")
    out = made_dir(a.out, "--out")
    try:
        options = AcquireOptions(start=a.from_group, session=a.session, evidence_set=a.evidence_set, baud=a.baud,
                                 yes=a.yes)
        acquire(a.plan, a.port, out, options=options, ask=_answer)
    except LabArgumentError as e:
        raise UsageError(str(e)) from None
    except LabError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


def _answer(question: str) -> str:
    try:
        return input(question)
    except EOFError:  # Ctrl-D: stop the session
        return "q"


def cmd_deploy(a) -> int:
    """One open-loop trial of the manifest's policy (docs/deployment.md). Numpy + dynamixel-sdk only.
    Every argument is checked (deploy/arguments.py) before the port opens."""
    from ..deploy import arguments
    from ..deploy.client import DeployError, run
    from ..deploy.manifest import ManifestError, load

    existing_file(a.manifest, "--manifest")
    if not a.dry_run and not a.port:
        raise UsageError("--port is required (or --dry-run)")
    if not a.dry_run and not a.yes and not sys.stdin.isatty():
        raise UsageError("--yes is required when stdin is not a terminal: nobody can be asked before the arm moves")
    try:
        man = load(a.manifest)
        got = arguments.check(man, a)
    except arguments.ArgumentError as e:
        raise UsageError(str(e)) from None
    except ManifestError as e:
        print(f"error: refused: {e}", file=sys.stderr)
        return 1
    except DeployError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    ask = None
    if not a.yes and not a.dry_run:
        ask = lambda: _ask("execute this trial on the arm? [y/N] ")  # noqa: E731
    try:
        r = run(a.manifest, a.port, got["target"], baud=got["baud"], out=got["out"], group_id=got["group_id"],
                placement=got["placement"], dry_run=a.dry_run, confirm=ask)
    except DeployError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    if not a.dry_run:
        print(f"trial complete: {len(r['log'])} cycles, torque off" + (f", written to {a.out}" if a.out else ""))
    return 0


def _ask(question: str) -> bool:
    try:
        return input(question).strip().lower() == "y"
    except EOFError:  # Ctrl-D: no
        return False


def cmd_deploy_index(a) -> int:
    """The deployment index of trials recorded in the lab: each group folder that passes the gate
    enters `index.csv`; aborted and rejected trials go to `aborted.json` with their cause."""
    from ..deploy import trials as T
    from ..lineage.groups import deployment_dir
    from ..validate import Limits

    cfg = load_config(a)
    raw = Path(a.raw if a.raw is not None else deployment_dir(cfg["raw_data"]["dir"]))
    if a.raw is not None:
        existing_dir(raw, "--raw")
    found = T.lab_trials(raw)
    if not found:
        print(f"error: {raw}: no trial (no groups/*/meta.json, no aborted/*.json; record with esnap deploy --out)",
              file=sys.stderr)
        return 1
    rows, aborted = T.gate(raw, found, Limits.from_config(cfg))
    planned = a.planned or len(found)
    if planned < len(found):
        print(f"error: --planned {planned}: {len(found)} trials found", file=sys.stderr)
        return 1
    T.write(rows, aborted, planned, raw / "index.csv", raw / "aborted.json")
    for r in aborted:
        print(f"{r['group_id']}: not indexed: {r['cause']}")
    print(f"{len(rows)} of {planned} planned trials indexed in {raw / 'index.csv'}; "
          f"{len(aborted)} listed in {raw / 'aborted.json'}")
    return 0

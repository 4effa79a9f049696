"""`esnap`: the project's command line. Each subcommand is a thin call into the package.

Every bad invocation is one line on stderr: exit status 2 for a usage error (a bad argument, a
missing file, a config that breaks the schema), 1 for a check that failed, 130 on Ctrl-C; a closed
pipe (`esnap claims | head`) ends quietly. Anything else is a bug: one "internal error" line, and
ESNAP_DEBUG=1 shows its traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path


class UsageError(Exception):
    """A bad argument: one line on stderr, exit status 2. `prog`: the (sub)command it is about."""

    def __init__(self, message: str, prog: str | None = None):
        super().__init__(message)
        self.prog = prog


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not argparse's usage block
        raise UsageError(f"{message} (see: {self.prog} --help)", self.prog)


def _path(path, what: str) -> Path:
    if not str(path).strip():  # Path("") is "."
        raise UsageError(f"{what}: empty path")
    return Path(path)


def _dir(path, what: str) -> Path:
    if not _path(path, what).is_dir():
        raise UsageError(f"{what} {path}: no such directory")
    return Path(path)


def _file(path, what: str) -> Path:
    if not _path(path, what).is_file():
        raise UsageError(f"{what} {path}: no such file")
    return Path(path)


def _made_dir(path, what: str) -> Path:
    """A directory to write into, made now (before any work) if it is not there."""
    try:
        _path(path, what).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"{what} {path}: cannot make it a directory ({e.strerror or e})") from None
    return Path(path)


def _config(a, root=".") -> dict:
    """The run's config: config.yaml, --configfile, --config (embodied_snap/runconfig.py)."""
    from . import runconfig

    return runconfig.load(a.configfile, a.config, root=root)


def _acquire(args):
    from .protocol import from_params
    from .twin.acquire import acquire_groups

    part, raw, seed, proto, dt, hold = args
    return acquire_groups(part, raw, seed=seed, proto=from_params(proto), dt=dt, hold=hold, progress=False)


def cmd_twin(a) -> int:
    """The simulated rig outside Snakemake: the same plan, seeds and writer as the workflow."""
    import time
    from multiprocessing import Pool

    from . import protocol
    from .plan import PlanError, load_plan
    from .rawformat import RecordingError, write_index, write_json
    from .twin.truth import truth

    cfg = _config(a)
    raw = Path(a.raw_dir if a.raw_dir is not None else cfg["raw_data"]["dir"])
    (_dir if a.action == "phenomena" else _path)(raw, "--raw-dir")
    try:
        plan = load_plan(cfg, raw)
    except (PlanError, RecordingError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    unknown = sorted(set(a.evidence_set or []) - set(plan.evidence_set))
    if unknown:
        known = ", ".join(sorted(set(plan.evidence_set)))
        raise UsageError(f"--evidence-set {', '.join(unknown)}: not in the plan ({known})")
    if a.evidence_set:
        plan = plan[plan.evidence_set.isin(a.evidence_set)]
    if a.action == "phenomena":
        from .twin.phenomena import phenomena

        try:
            print(json.dumps(phenomena(raw, plan, protocol.load(cfg)), indent=1))
        except FileNotFoundError as e:
            print(f"error: {raw}: {e.filename} missing (record the groups first: esnap twin acquire)", file=sys.stderr)
            return 1
        return 0
    _made_dir(raw, "--raw-dir")  # after every check: a refused command leaves nothing behind
    t0 = time.perf_counter()
    # Every group's randomness comes from (seed, group_id) alone, so any partition gives the same bytes.
    proto = protocol.params(cfg, *protocol.ACQUISITION)
    tw = cfg["twin"]
    parts = [(plan.iloc[k :: a.jobs], raw, cfg["seed"], proto, tw["dt"], tw["held_base"]) for k in range(a.jobs)]
    with Pool(a.jobs) as pool:
        rows = [r for part in pool.map(_acquire, parts) for r in part]
    write_index(rows, raw / "index.csv")
    write_json(truth(cfg["seed"], cfg["sessions"]), raw / "twin_truth.json")
    print(f"{len(rows)} groups written to {raw} in {time.perf_counter() - t0:.1f} s ({a.jobs} jobs)")
    return 0


def _tree_config(a) -> dict:
    from . import runconfig

    cfg = _config(a)
    cfg["raw_data"] = {**cfg["raw_data"], "dir": a.raw_dir if a.raw_dir is not None else cfg["raw_data"]["dir"]}
    _dir(cfg["raw_data"]["dir"], "recording tree")
    if a.source:
        cfg["raw_data"]["source"] = a.source
    if getattr(a, "exclude", None):
        cfg["raw_data"]["exclude"] = a.exclude
    return runconfig.validate(cfg)


def _fits_tree(a, cfg: dict) -> None:
    """A tree recorded for another budget is refused in one line with the command that fits it
    (docs/design.md, "Budgets"), before the gate reports its split sizes."""
    from . import budget

    try:
        budget.check_tree(cfg, cfg["raw_data"]["dir"], argv=a.argv)
    except budget.BudgetError as e:
        raise UsageError(str(e)) from None


def _fits_run(a, cfg: dict | None) -> None:
    """A config asking for another budget than the one results/ holds: one line, before any record is read."""
    from . import budget

    if cfg is not None:
        try:
            budget.fits(cfg, a.root, argv=a.argv)
        except budget.BudgetError as e:
            raise UsageError(str(e)) from None


def cmd_validate(a) -> int:
    """Exactly what the workflow checks before its DAG (verdicts.check_tree): one line on error.
    --partial: the same gate on a tree holding part of the corpus, and which sets it lacks."""
    from .lineage.policy import needs
    from .plan import PlanError
    from .rawformat import EVIDENCE_SETS
    from .validate import RecordingError
    from .verdicts import check_tree

    cfg = _tree_config(a)
    _fits_tree(a, cfg)
    try:
        plan = check_tree(cfg, cfg["raw_data"]["dir"], partial=a.partial)
    except (RecordingError, PlanError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    ex = plan.attrs["excluded"]
    line = f"{len(plan)} groups valid"
    if a.partial:
        def short(rules):  # a stage's rules as one entry: policy_* (6)
            stages = [r.split("_")[0] for r in rules]
            out = [f"{p}_* ({stages.count(p)})" if stages.count(p) > 4 else r for r, p in zip(rules, stages)]
            return ", ".join(dict.fromkeys(out))

        counts = plan.evidence_set.value_counts()  # the sets held, and those the budget asks for that it lacks
        present = {es: int(counts[es]) for es in EVIDENCE_SETS if es in counts}
        asked = cfg["budgets"][cfg["budget"]]["groups"]
        missing = {es: needs(es) for es in EVIDENCE_SETS if es in asked and es not in present}
        line += f" (partial corpus: {', '.join(f'{es} {n}' for es, n in present.items()) or 'no groups'})"
        line += f"; missing: {'; '.join(f'{es} (needed by {short(r)})' for es, r in missing.items()) or 'none'}"
    print(line + (f"; excluded: {', '.join(f'{g} ({r})' for g, r in ex.items())}" if ex else ""))
    return 0


def cmd_seal(a) -> int:
    """Re-seal: record the sealed set of the current plan, saying what it was and what it is now."""
    import json as _json

    from . import sealed
    from .plan import PlanError, load_plan
    from .validate import Limits, RecordingError
    from .verdicts import Verdicts, index_rows

    cfg = _tree_config(a)
    _fits_tree(a, cfg)
    raw = cfg["raw_data"]["dir"]
    try:
        plan = load_plan(cfg, raw)
        lim = Limits.from_config(cfg)
        ids = list(plan[plan.role == "sealed"].group_id)
        Verdicts(raw, lim, index_rows(raw, plan, lim.group_id_pattern), None).check(ids)
    except (RecordingError, PlanError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    path = sealed.record_path(raw)
    was = sorted(_json.loads(path.read_text())["groups"]) if path.exists() else []
    sealed.seal(raw, plan, "esnap seal")
    print(f"sealed set: {len(ids)} groups: {', '.join(ids)}; was: {', '.join(was) or 'none'}; recorded in {path}")
    return 0


def cmd_import(a) -> int:
    """A capture session's exports into the recording tree, through the gate; all takes or none."""
    from .capture.errors import CaptureError
    from .capture.importer import ImportRefused, import_session
    from .capture.lab import load_lab

    cfg = _config(a)
    session, lab_path = _file(a.session, "SESSION"), _file(a.lab, "--lab")
    raw = _path(a.raw if a.raw is not None else cfg["raw_data"]["dir"], "--raw")
    if raw.exists() and not raw.is_dir():
        raise UsageError(f"--raw {raw}: not a directory")
    try:
        lab = load_lab(lab_path)
        progress = None
        if not a.quiet:
            from tqdm import tqdm

            def progress(specs):
                return tqdm(specs, desc="import", unit="take", file=sys.stderr)

        rows = import_session(session, lab, raw, cfg, progress=progress)
    except (CaptureError, ImportRefused) as e:
        print(f"error: {_one_line(e)} (nothing written to {raw})", file=sys.stderr)
        return 1
    for k, want in ((k, cfg["rig"][k]) for k in lab.arm):  # the lab schema's arm keys are config rig keys
        if lab.arm[k] != want:
            print(f"note: {lab_path}: arm.{k} is {lab.arm[k]} and the config's rig.{k} {want}: the fits use the "
                  f"config's; set rig.{k} in config.yaml to the lab's", file=sys.stderr)
    ids = [r["group_id"] for r in rows]
    print(f"{len(rows)} takes imported into {raw}: {', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''}")
    return 0


def _run_config(a) -> dict | None:
    """The config named on the command line (--configfile, --config), None when neither is given
    (then: the config the last run recorded)."""
    from . import runconfig

    return _config(a, root=a.root) if runconfig.given(a) else None


def cmd_audit(a) -> int:
    from .lineage.audit import audit, format_audit

    _dir(a.root, "--root")
    cfg = _run_config(a)
    _fits_run(a, cfg)
    if not (Path(a.root) / _path(a.result, "RESULT")).exists():
        if ":" not in a.result and "/" in a.result:
            raise UsageError(f"{a.result}: no such file or directory under {a.root}")
        return _audit_number(a)  # CLAIM_ID or FILE:KEY
    report = audit(a.result, root=a.root, config=cfg)
    print(json.dumps(report, indent=1, default=str) if a.json else format_audit(report))
    return 1 if report.get("stale") else 0


def _audit_number(a) -> int:
    from .lineage.numbers import NumberError, audit_number, format_number

    try:
        r = audit_number(a.result, root=a.root)
    except NumberError as e:
        raise UsageError(str(e)) from None
    print(json.dumps(r, indent=1, default=str) if a.json else format_number(r))
    return 1 if r["stale"] else 0


def cmd_check_separation(a) -> int:
    from .lineage.checks import check

    _dir(a.root, "--root")
    cfg = _run_config(a)
    _fits_run(a, cfg)
    res = check(a.root, static=not a.no_static, records=not a.no_records, config_overrides=cfg)
    for v in res["violations"]:
        print(f"leak: {v}")
    print("separation holds" if res["ok"] else f"{len(res['violations'])} separation violation(s)")
    return 0 if res["ok"] else 1


def cmd_prov(a) -> int:
    from .lineage.prov import export

    _dir(a.root, "--root")
    _path(a.out, "--out")
    try:
        print(export(a.root, a.out))
    except OSError as e:
        raise UsageError(f"--out {a.out}: cannot write it ({e.strerror or e})") from None
    return 0


def cmd_resources(a) -> int:
    from .lineage.dag import rule_table
    from .lineage.records import instance
    from .resources import ResourceError, render, set_resources, updated_profile

    _dir(a.root, "--root")
    _dir(a.benchmarks, "--benchmarks")
    _file(a.profile, "--profile")
    try:
        table = rule_table(a.root)
        per_shard = {r for r in table if instance(r, {})[0] != r}  # names that follow the budget's shards
        res, missing = set_resources(a.benchmarks, table, per_shard)
    except ResourceError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    profile = Path(a.profile)
    old = profile.read_text()
    new = updated_profile(old, render(res, missing))
    if missing:
        print(f"warning: not measured in {a.benchmarks} (default-resources): {', '.join(missing)}", file=sys.stderr)
    if a.check:
        if new != old:
            print(f"{profile}: set-resources differ from {a.benchmarks} (run esnap resources)", file=sys.stderr)
            return 1
        print(f"{profile}: set-resources match {a.benchmarks}")
        return 0
    profile.write_text(new)
    print(f"{profile}: set-resources of {len(res)} rules from {a.benchmarks}")
    return 0


def cmd_lab_plan(a) -> int:
    """The sessions a lab records for a budget (docs/lab.md): the acquisition protocol's
    groups, programs and operator steps, the targets where the simulated rig's model of the arm
    says the cup strikes."""
    from .lab import plan as LP
    from .twin.acquire import place_target  # a suggestion for the operator; the capture measures it

    cfg = _config(a)
    budget = a.budget or cfg["budget"]
    if budget not in cfg["budgets"]:
        raise UsageError(f"--budget {budget}: not a budget of the config ({', '.join(cfg['budgets'])})")
    out = _path(a.out, "--out")
    if out.is_dir():
        raise UsageError(f"--out {out}: a directory; give the plan file to write")
    if out.exists() and not a.force:
        raise UsageError(f"--out {out}: exists (a plan being recorded is never rewritten; --force to replace it)")
    if not out.absolute().parent.is_dir():
        raise UsageError(f"--out {out}: {out.absolute().parent} is not a directory")
    proto = None
    if not a.no_targets:
        from . import protocol

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
    from .lab.acquire import LabArgumentError, LabError, acquire

    _file(a.plan, "--plan")
    if not a.port or not a.port.strip():
        raise UsageError("--port: empty (the servo bus, e.g. /dev/ttyUSB0)")
    if not os.path.exists(a.port):
        raise UsageError(f"--port {a.port}: no such device")
    if not a.yes and not sys.stdin.isatty():
        raise UsageError("--yes is required when stdin is not a terminal: nobody can be asked before the arm moves")
    out = _made_dir(a.out, "--out")
    try:
        acquire(a.plan, a.port, out, start=a.from_group, yes=a.yes, baud=a.baud, session=a.session,
                evidence_set=a.evidence_set, ask=_answer)
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
    from .deploy import arguments
    from .deploy.client import DeployError, run
    from .deploy.manifest import ManifestError, load

    _file(a.manifest, "--manifest")
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
    from .deploy import trials as T
    from .lineage.groups import deployment_dir
    from .validate import Limits

    cfg = _config(a)
    raw = Path(a.raw if a.raw is not None else deployment_dir(cfg["raw_data"]["dir"]))
    if a.raw is not None:
        _dir(raw, "--raw")
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


def cmd_claims(a) -> int:
    """The claims ledger, filtered by paper section and status."""
    from .paper.ledger import COLUMNS, STATUSES, count_line, read
    from .paper.sections import section_key

    for s in a.status or []:
        if s not in STATUSES:
            raise UsageError(f"--status {s}: no such claim status (statuses: {', '.join(STATUSES)})")
    path = Path(_dir(a.root, "--root")) / a.ledger
    if not path.is_file():
        print(f"error: {a.ledger}: no claims ledger (run: snakemake results/tables/claims.csv)", file=sys.stderr)
        return 1
    try:
        rows = read(path)
    except (OSError, UnicodeDecodeError) as e:
        print(f"error: {a.ledger}: cannot read the claims ledger ({e})", file=sys.stderr)
        return 1
    lacks = sorted(set(COLUMNS) - set(rows[0])) if rows else []
    if lacks:
        print(f"error: {a.ledger}: not a claims ledger (no column {', '.join(lacks)})", file=sys.stderr)
        return 1
    sections = sorted({r["section"] for r in rows}, key=section_key)
    for s in a.section or []:
        if s not in sections:
            raise UsageError(f"--section {s}: no such section in {a.ledger} "
                             f"(sections: {', '.join(sections) or 'none'})")
    rows = [r for r in rows if (not a.section or r["section"] in a.section)
            and (not a.status or r["status"] in a.status)]
    print(count_line(rows))
    w = max([len(r["claim_id"]) for r in rows] + [8])
    for r in rows:
        doc = f"  -> {r['explained_in']}" if r["explained_in"] else ""
        print(f"{r['section']:<8} {r['claim_id']:<{w}} paper {r['paper'] or '-':<16} ours {r['ours'] or '-':<20} "
              f"{r['unit']:<10} {r['status']}{doc}")
    return 0


def cmd_crate(a) -> int:
    from .paper.crate import verify, write

    _dir(a.root, "--root")
    if a.verify:
        meta = Path(a.root) / a.out / "ro-crate-metadata.json"
        if not meta.is_file():
            print(f"error: {a.out}: no crate (no ro-crate-metadata.json; write it: esnap crate)", file=sys.stderr)
            return 1
        bad = verify(a.root, a.out.rstrip("/"))
        for b in bad:
            print(f"error: {b}")
        print("crate matches results/" if not bad else f"{len(bad)} result file(s) differ from the crate")
        return 1 if bad else 0
    _path(a.out, "--out")
    try:
        print(write(a.root, a.out.rstrip("/")))
    except OSError as e:
        raise UsageError(f"--out {a.out}: cannot write the crate there ({e.strerror or e})") from None
    return 0


def cmd_budget(a) -> int:
    """Switch raw_data/ and results/ to another budget's run, keeping this one's (docs/design.md)."""
    from . import budget

    cfg = _config(a)
    if a.show and a.name is not None:
        raise UsageError(f"{a.name!r} and --show: give one")
    if a.show:
        print(budget.shown(cfg))
        return 0
    try:
        print(budget.switch(cfg, cfg["budget"] if a.name is None else a.name))
    except budget.BudgetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


def cmd_report_check(a) -> int:
    _file(a.html, "report")
    _path(a.screenshot, "--screenshot")
    try:
        from playwright.sync_api import Error as PlaywrightError
    except ImportError:
        print("error: report-check needs playwright (pip install -e '.[dev]')", file=sys.stderr)
        return 1

    from .paper.browser import check_report

    try:
        res = check_report(a.html, a.screenshot)
    except PlaywrightError as e:
        print(f"error: headless Chromium: {str(e).splitlines()[0]}", file=sys.stderr)
        return 1
    for path, what in res["results"].items():
        print(f"{path}: {what}")
    for prob in res["problems"]:
        print(f"error: {prob}")
    print("report ok" if not res["problems"] else f"{len(res['problems'])} problem(s)")
    return 1 if res["problems"] else 0


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("embodied-snap")
    except PackageNotFoundError:  # run from a checkout that was never installed
        return "unknown (not installed)"


def _positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n}: expected 1 or more")
    return n


def _config_args(sp, default_help: str = "default: config.yaml") -> None:
    from . import runconfig

    runconfig.add_arguments(sp, default_help)


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="esnap", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")

    t = sub.add_parser("twin", help="the simulated rig outside Snakemake: record groups, or measure its phenomena")
    t.add_argument("action", choices=["acquire", "phenomena"])
    _config_args(t)
    t.add_argument("--raw-dir")
    t.add_argument("--evidence-set", action="append", help="only these evidence sets (repeatable)")
    t.add_argument("--jobs", type=_positive, default=2, help="processes to simulate in")
    t.set_defaults(fn=cmd_twin)

    for name, fn, hlp in (
        ("validate", cmd_validate, "check a recording tree through the gate, as the workflow does before its DAG "
                                   "(--partial: a tree holding part of the corpus, e.g. one session)"),
        ("seal", cmd_seal, "re-seal: record the current sealed test set (after a deliberate change to it)"),
    ):
        v = sub.add_parser(name, help=hlp)
        v.add_argument("raw_dir", nargs="?", help="recording tree (default: config raw_data.dir)")
        _config_args(v, "default: config.yaml; its gate:, raw_data: and budget")
        v.add_argument("--source", choices=["rig", "twin"], default="rig" if name == "validate" else None,
                       help="plan from index.csv (rig) or from the budget (twin); seal: default from config")
        v.add_argument("--exclude", action="append", help="leave this group out, as raw_data.exclude (repeatable)")
        if name == "validate":
            v.add_argument("--partial", action="store_true",
                           help="the tree holds part of the corpus (a session): every group through the same "
                                "gate, no split drawn (no split-size rule), the sealed groups it holds against "
                                "sealed.json; says which evidence sets are missing and what needs them. "
                                "Without it the corpus is complete, as the workflow needs it")
        v.set_defaults(fn=fn)

    im = sub.add_parser("import", help="a capture session's exports (Motive CSV, C3D) and servo logs into the "
                                       "recording tree, one group per take, through the gate")
    im.add_argument("session", metavar="SESSION", help="the session file: which take is which group (docs/data.md)")
    im.add_argument("--lab", required=True,
                    help="the lab file: bodies, axes, servo ids, clock (docs/examples/lab.yaml)")
    im.add_argument("--raw", help="recording tree to add the groups to (default: config raw_data.dir)")
    im.add_argument("--quiet", action="store_true", help="no progress bar")
    _config_args(im, "default: config.yaml; its gate:, resample: and characterize:")
    im.set_defaults(fn=cmd_import)

    au = sub.add_parser("audit", help="which recordings fed RESULT (a file, a claim id or FILE:KEY), which never "
                                      "did, and whether it is stale")
    au.add_argument("result", metavar="RESULT", help="a file or directory of the run, a claim id of the ledger "
                    "(tendon_travel_per_tick_um), or FILE:KEY (results/characterize/servo.json:rate_tick_s)")
    au.add_argument("--root", default=".")
    au.add_argument("--json", action="store_true")
    _config_args(au, "default: the config the last run recorded")
    au.set_defaults(fn=cmd_audit)

    cs = sub.add_parser("check-separation", help="prove the evidence-set separation (docs/design.md section 3)")
    _config_args(cs, "default: the config the last run recorded")
    cs.add_argument("--root", default=".")
    cs.add_argument("--no-static", action="store_true", help="skip the Snakemake DAG check")
    cs.add_argument("--no-records", action="store_true", help="skip the provenance-record check")
    cs.set_defaults(fn=cmd_check_separation)

    pr = sub.add_parser("prov", help="export the run's provenance as W3C PROV-JSON")
    pr.add_argument("--root", default=".")
    pr.add_argument("--out", default="results/lineage/prov.json")
    pr.set_defaults(fn=cmd_prov)

    rs = sub.add_parser("resources", help="write the SLURM profile's set-resources from a paper run's benchmarks")
    rs.add_argument("--benchmarks", default="benchmarks", help="benchmarks/ of a paper-budget run")
    rs.add_argument("--profile", default="profiles/slurm/config.yaml")
    rs.add_argument("--root", default=".", help="the workflow (its rules' benchmarks and threads)")
    rs.add_argument("--check", action="store_true", help="only compare; exit 1 when the profile differs")
    rs.set_defaults(fn=cmd_resources)

    lb = sub.add_parser("lab", help="the paper's acquisition on the lab's arm: plan the sessions, record them")
    lsub = lb.add_subparsers(dest="lab_cmd", required=True, metavar="ACTION")
    lp = lsub.add_parser("plan", help="the sessions to record for a budget, in the order an operator works")
    lp.add_argument("--budget", help="paper, quick or smoke (default: config.yaml's budget)")
    lp.add_argument("--out", required=True, help="the plan file to write (YAML)")
    lp.add_argument("--no-targets", action="store_true",
                    help="no suggested target positions (they come from the simulated rig's model of the arm)")
    lp.add_argument("--force", action="store_true", help="replace an existing plan file")
    _config_args(lp, "default: config.yaml; its budgets, seed, deployment bus settings")
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

    di = sub.add_parser("deploy-index", help="index the deployment trials recorded in the lab (Table II, Fig. 7)")
    di.add_argument("--raw", help="the deployment recording tree (default: <raw_data.dir>/deployment)")
    _config_args(di, "default: config.yaml; its gate and raw_data.dir")
    di.add_argument("--planned", type=_positive, help="trials planned (default: those found); Table II's denominator")
    di.set_defaults(fn=cmd_deploy_index)

    cl = sub.add_parser("claims", help="the claims ledger: every paper number beside ours, by section and status")
    cl.add_argument("--section", action="append", help="only this paper section, e.g. III-B (repeatable)")
    cl.add_argument("--status", action="append", help="only claims with this status, e.g. differs (repeatable)")
    cl.add_argument("--root", default=".")
    cl.add_argument("--ledger", default="results/tables/claims.csv")
    cl.set_defaults(fn=cmd_claims)

    cr = sub.add_parser("crate", help="write the run as a Workflow Run RO-Crate (or --verify it against results/)")
    cr.add_argument("--out", default="results/crate/")
    cr.add_argument("--root", default=".")
    cr.add_argument("--verify", action="store_true", help="check that every result file is in it with its sha256")
    cr.set_defaults(fn=cmd_crate)

    bu = sub.add_parser("budget",
                        help="switch raw_data/ and results/ to another budget's run (the current one is kept)")
    bu.add_argument("name", nargs="?", help="paper, quick or smoke (default: config.yaml's budget)")
    bu.add_argument("--show", action="store_true", help="print the budget raw_data/ and results/ hold, and stop")
    _config_args(bu)
    bu.set_defaults(fn=cmd_budget)

    rc = sub.add_parser("report-check", help="open the HTML report in headless Chromium: every figure and table shown")
    rc.add_argument("html", nargs="?", default="results/report.html")
    rc.add_argument("--screenshot", default="results/report.png")
    rc.set_defaults(fn=cmd_report_check)
    return p


def _config_last(argv: list[str]) -> list[str]:
    """`--config K=V ...` moved to the end (before any `--`): it takes every K=V after it, and at
    the end it cannot swallow a positional (`esnap audit --config budget=smoke RESULT`)."""
    head, moved, i = [], [], 0
    while i < len(argv):
        if argv[i] == "--":
            break
        if argv[i] == "--config":
            j = i + 1
            while j < len(argv) and "=" in argv[j] and not argv[j].startswith("-"):
                j += 1
            moved += argv[i:j]
            i = j
        else:
            head.append(argv[i])
            i += 1
    return head + moved + argv[i:]


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def main(argv: list[str] | None = None) -> int:
    from .runconfig import ConfigError

    argv = _config_last(list(sys.argv[1:] if argv is None else argv))
    prog = "esnap"
    try:
        a = parser().parse_args(argv)
        a.argv = ["esnap", *argv]  # the command as given, for a line that says how to ask again
        prog = f"esnap {a.cmd}"
        rc = a.fn(a)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return rc
    except UsageError as e:
        print(f"{e.prog or prog}: error: {e}", file=sys.stderr)
        return 2
    except ConfigError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader has gone (`esnap claims | head`): what it read was all it wanted
        _stdout_to_devnull()
        return 141  # as a shell reports a process that SIGPIPE ended
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 -- a bug: one line here, the traceback on request
        if os.environ.get("ESNAP_DEBUG") == "1":
            raise
        print(f"{prog}: internal error: {type(e).__name__}: {_one_line(e)} (ESNAP_DEBUG=1 shows the traceback)",
              file=sys.stderr)
        return 1


def _stdout_to_devnull() -> None:
    """So that the interpreter's last flush of stdout does not fail on the closed pipe too."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # not a real file (a test's capture): nothing to flush there
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())

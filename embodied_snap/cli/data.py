"""The recording tree's commands: `esnap twin` (the simulated rig records it), `validate` and `seal`
(the gate the workflow runs before its DAG), `import` (a capture session's exports into it)."""

from __future__ import annotations

import json
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
    one_line,
    positive,
)


def add_twin(sub) -> None:
    t = sub.add_parser("twin", help="the simulated rig outside Snakemake: record groups, or measure its phenomena")
    t.add_argument("action", choices=["acquire", "phenomena"])
    config_args(t)
    t.add_argument("--raw-dir")
    t.add_argument("--evidence-set", action="append", help="only these evidence sets (repeatable)")
    t.add_argument("--jobs", type=positive, default=2, help="processes to simulate in")
    t.set_defaults(fn=cmd_twin)


def add_gate(sub) -> None:
    """`validate` and `seal`: the same recording tree and config arguments."""
    for name, fn, hlp in (
        ("validate", cmd_validate, "check a recording tree through the gate, as the workflow does before its DAG "
                                   "(--partial: a tree holding part of the corpus, e.g. one session)"),
        ("seal", cmd_seal, "re-seal: record the current sealed test set (after a deliberate change to it)"),
    ):
        v = sub.add_parser(name, help=hlp)
        v.add_argument("raw_dir", nargs="?", help="recording tree (default: config raw_data.dir)")
        config_args(v, "default: config.yaml; its gate:, raw_data: and budget")
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


def add_import(sub) -> None:
    im = sub.add_parser("import", help="a capture session's exports (Motive CSV, C3D) and servo logs into the "
                                       "recording tree, one group per take, through the gate")
    im.add_argument("session", metavar="SESSION", help="the session file: which take is which group (docs/data.md)")
    im.add_argument("--lab", required=True,
                    help="the lab file: bodies, axes, servo ids, clock (docs/examples/lab.yaml)")
    im.add_argument("--raw", help="recording tree to add the groups to (default: config raw_data.dir)")
    im.add_argument("--quiet", action="store_true", help="no progress bar")
    config_args(im, "default: config.yaml; its gate:, resample: and characterize:")
    im.set_defaults(fn=cmd_import)


def _acquire(args):
    from ..protocol import from_params
    from ..twin.acquire import acquire_groups

    part, raw, seed, proto, dt, hold = args
    return acquire_groups(part, raw, seed=seed, proto=from_params(proto), dt=dt, hold=hold, progress=False)


def cmd_twin(a) -> int:
    """The simulated rig outside Snakemake: the same plan, seeds and writer as the workflow."""
    import time
    from multiprocessing import Pool

    from .. import protocol
    from ..io import write_json
    from ..plan import PlanError, load_plan
    from ..rawformat import RecordingError, write_index
    from ..twin.truth import truth

    cfg = load_config(a)
    raw = Path(a.raw_dir if a.raw_dir is not None else cfg["raw_data"]["dir"])
    (existing_dir if a.action == "phenomena" else given_path)(raw, "--raw-dir")
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
        from ..twin.phenomena import phenomena

        try:
            print(json.dumps(phenomena(raw, plan, protocol.load(cfg)), indent=1))
        except FileNotFoundError as e:
            print(f"error: {raw}: {e.filename} missing (record the groups first: esnap twin acquire)", file=sys.stderr)
            return 1
        return 0
    made_dir(raw, "--raw-dir")  # after every check: a refused command leaves nothing behind
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
    from .. import runconfig

    cfg = load_config(a)
    cfg["raw_data"] = {**cfg["raw_data"], "dir": a.raw_dir if a.raw_dir is not None else cfg["raw_data"]["dir"]}
    existing_dir(cfg["raw_data"]["dir"], "recording tree")
    if a.source:
        cfg["raw_data"]["source"] = a.source
    if getattr(a, "exclude", None):
        cfg["raw_data"]["exclude"] = a.exclude
    return runconfig.validate(cfg)


def _fits_tree(a, cfg: dict) -> None:
    """A tree recorded for another budget is refused in one line with the command that fits it
    (docs/design.md, "Budgets"), before the gate reports its split sizes."""
    from .. import budget

    try:
        budget.check_tree(cfg, cfg["raw_data"]["dir"], argv=a.argv)
    except budget.BudgetError as e:
        raise UsageError(str(e)) from None


def cmd_validate(a) -> int:
    """Exactly what the workflow checks before its DAG (verdicts.check_tree): one line on error.
    --partial: the same gate on a tree holding part of the corpus, and which sets it lacks."""
    from ..lineage.policy import needs
    from ..plan import PlanError
    from ..rawformat import EVIDENCE_SETS
    from ..validate import RecordingError
    from ..verdicts import check_tree

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
    from .. import sealed
    from ..plan import PlanError, load_plan
    from ..validate import Limits, RecordingError
    from ..verdicts import Verdicts, index_rows

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
    was = sorted(json.loads(path.read_text())["groups"]) if path.exists() else []
    sealed.seal(raw, plan, "esnap seal")
    print(f"sealed set: {len(ids)} groups: {', '.join(ids)}; was: {', '.join(was) or 'none'}; recorded in {path}")
    return 0


def cmd_import(a) -> int:
    """A capture session's exports into the recording tree, through the gate; all takes or none."""
    from ..capture.errors import CaptureError
    from ..capture.importer import ImportRefused, import_session
    from ..capture.lab import load_lab

    cfg = load_config(a)
    session, lab_path = existing_file(a.session, "SESSION"), existing_file(a.lab, "--lab")
    raw = given_path(a.raw if a.raw is not None else cfg["raw_data"]["dir"], "--raw")
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
        print(f"error: {one_line(e)} (nothing written to {raw})", file=sys.stderr)
        return 1
    for k, want in ((k, cfg["rig"][k]) for k in lab.arm):  # the lab schema's arm keys are config rig keys
        if lab.arm[k] != want:
            print(f"note: {lab_path}: arm.{k} is {lab.arm[k]} and the config's rig.{k} {want}: the fits use the "
                  f"config's; set rig.{k} in config.yaml to the lab's", file=sys.stderr)
    ids = [r["group_id"] for r in rows]
    print(f"{len(rows)} takes imported into {raw}: {', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''}")
    return 0

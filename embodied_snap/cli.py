"""`esnap`: the project's command line. Each subcommand is a thin call into the package."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _config(path: str, budget: str | None) -> dict:
    import yaml  # not at the top: `esnap deploy` runs on the lab PC with numpy and dynamixel-sdk alone

    with open(path) as f:
        cfg = yaml.safe_load(f)
    if budget:
        cfg["budget"] = budget
    return cfg


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
    from .plan import load_plan
    from .rawformat import write_index, write_json
    from .twin.truth import truth

    cfg = _config(a.config, a.budget)
    raw = Path(a.raw_dir or cfg["raw_data"]["dir"])
    plan = load_plan(cfg, raw)
    if a.evidence_set:
        plan = plan[plan.evidence_set.isin(a.evidence_set)]
    if a.action == "phenomena":
        from .twin.phenomena import phenomena

        print(json.dumps(phenomena(raw, plan, protocol.load(cfg)), indent=1))
        return 0
    t0 = time.perf_counter()
    # Every group's randomness comes from (seed, group_id) alone, so any partition gives the same bytes.
    proto = protocol.params(cfg, "primitive", "rig", "thresholds")
    tw = cfg["twin"]
    parts = [(plan.iloc[k :: a.jobs], raw, cfg["seed"], proto, tw["dt"], tw["held_base"]) for k in range(a.jobs)]
    with Pool(a.jobs) as pool:
        rows = [r for part in pool.map(_acquire, parts) for r in part]
    write_index(rows, raw / "index.csv")
    write_json(truth(cfg["seed"], cfg["sessions"]), raw / "twin_truth.json")
    print(f"{len(rows)} groups written to {raw} in {time.perf_counter() - t0:.1f} s ({a.jobs} jobs)")
    return 0


def _tree_config(a) -> dict:
    cfg = _config(a.config, a.budget)
    cfg["raw_data"] = {**cfg["raw_data"], "dir": a.raw_dir or cfg["raw_data"]["dir"]}
    if a.source:
        cfg["raw_data"]["source"] = a.source
    if getattr(a, "exclude", None):
        cfg["raw_data"]["exclude"] = a.exclude
    return cfg


def cmd_validate(a) -> int:
    """Exactly what the workflow checks before its DAG (verdicts.check_tree): one line on error."""
    from .plan import PlanError
    from .validate import RecordingError
    from .verdicts import check_tree

    cfg = _tree_config(a)
    try:
        plan = check_tree(cfg, cfg["raw_data"]["dir"])
    except (RecordingError, PlanError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    ex = plan.attrs["excluded"]
    print(f"{len(plan)} groups valid" + (f"; excluded: {', '.join(f'{g} ({r})' for g, r in ex.items())}" if ex else ""))
    return 0


def cmd_seal(a) -> int:
    """Re-seal: record the sealed set of the current plan, saying what it was and what it is now."""
    import json as _json

    from . import sealed
    from .plan import PlanError, load_plan
    from .validate import Limits, RecordingError
    from .verdicts import Verdicts, index_rows

    cfg = _tree_config(a)
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


def _run_config(a) -> dict | None:
    """The config named on the command line, as Snakemake takes it (--configfile, then --config
    KEY=VALUE with YAML values); None when neither is given (then: the last run's, from the records)."""
    if not a.config and not a.configfile:
        return None
    import yaml

    cfg = _config(Path(a.root) / (a.configfile or "config.yaml"), None)
    for kv in a.config or []:
        key, sep, val = kv.partition("=")
        if not sep:
            raise SystemExit(f"esnap: --config {kv}: expected KEY=VALUE")
        cfg[key] = yaml.safe_load(val)
    return cfg


def _config_args(sp) -> None:
    sp.add_argument("--configfile", help="the run's config file (default with --config: config.yaml)")
    sp.add_argument("--config", nargs="+", metavar="KEY=VALUE",
                    help="config overrides as for snakemake (default: the config the last run recorded)")


def cmd_audit(a) -> int:
    from .lineage.audit import audit, format_audit

    report = audit(a.result, root=a.root, config=_run_config(a))
    print(json.dumps(report, indent=1, default=str) if a.json else format_audit(report))
    return 1 if report.get("stale") else 0


def cmd_check_separation(a) -> int:
    from .lineage.checks import check

    res = check(a.root, static=not a.no_static, records=not a.no_records, config_overrides=_run_config(a))
    for v in res["violations"]:
        print(f"leak: {v}")
    print("separation holds" if res["ok"] else f"{len(res['violations'])} separation violation(s)")
    return 0 if res["ok"] else 1


def cmd_prov(a) -> int:
    from .lineage.prov import export

    print(export(a.root, a.out))
    return 0


def cmd_resources(a) -> int:
    from .lineage.dag import rule_table
    from .resources import ResourceError, render, set_resources, updated_profile

    try:
        res, missing = set_resources(a.benchmarks, rule_table(a.root))
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


def _target(a, man_path) -> list[float]:
    if a.target:
        return [float(x) for x in a.target.split(",")]
    if a.target_from_mocap:
        with open(a.target_from_mocap) as f:  # the mocap system's export: {"target_m": [x, y, z]} in the base frame
            return [float(x) for x in json.load(f)["target_m"]]
    if a.placement is None:
        raise SystemExit("error: give --target, --target-from-mocap or --placement")
    with open(man_path) as f:
        return json.load(f)["placements"][a.placement - 1]["target_m"]


def cmd_deploy(a) -> int:
    """One open-loop trial of the manifest's policy (docs/deployment.md). Numpy + dynamixel-sdk only."""
    from .deploy.client import DeployError, run

    if not a.dry_run and not a.port:
        print("error: --port is required (or --dry-run)", file=sys.stderr)
        return 2
    ask = None
    if not a.yes and not a.dry_run and sys.stdin.isatty():
        ask = lambda: input("execute this trial on the arm? [y/N] ").strip().lower() == "y"  # noqa: E731
    try:
        r = run(a.manifest, a.port, _target(a, a.manifest), baud=a.baud, out=a.out, group_id=a.group_id,
                placement=a.placement, dry_run=a.dry_run, confirm=ask)
    except DeployError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    if not a.dry_run:
        print(f"trial complete: {len(r['log'])} cycles, torque off" + (f", written to {a.out}" if a.out else ""))
    return 0


def cmd_deploy_index(a) -> int:
    """The deployment index of trials recorded in the lab: each group folder that passes the gate
    enters `index.csv`; aborted and rejected trials go to `aborted.json` with their cause."""
    from .deploy import trials as T
    from .lineage.groups import deployment_dir
    from .validate import Limits

    cfg = _config(a.config, None)
    raw = Path(a.raw or deployment_dir(cfg["raw_data"]["dir"]))
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
    from .paper.ledger import count_line, read

    path = Path(a.root) / a.ledger
    if not path.exists():
        print(f"error: {a.ledger}: no claims ledger (run: snakemake results/tables/claims.csv)", file=sys.stderr)
        return 1
    rows = [r for r in read(path) if (not a.section or r["section"] in a.section)
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

    if a.verify:
        bad = verify(a.root, a.out.rstrip("/"))
        for b in bad:
            print(f"error: {b}")
        print("crate matches results/" if not bad else f"{len(bad)} result file(s) differ from the crate")
        return 1 if bad else 0
    print(write(a.root, a.out.rstrip("/")))
    return 0


def cmd_report_check(a) -> int:
    from .paper.browser import check_report

    res = check_report(a.html, a.screenshot)
    for path, what in res["results"].items():
        print(f"{path}: {what}")
    for prob in res["problems"]:
        print(f"error: {prob}")
    print("report ok" if not res["problems"] else f"{len(res['problems'])} problem(s)")
    return 1 if res["problems"] else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="esnap", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)

    t = sub.add_parser("twin", help="the simulated rig outside Snakemake: record groups, or measure its phenomena")
    t.add_argument("action", choices=["acquire", "phenomena"])
    t.add_argument("--config", default="config.yaml")
    t.add_argument("--budget", choices=["paper", "quick", "smoke"])
    t.add_argument("--raw-dir")
    t.add_argument("--evidence-set", action="append", help="only these evidence sets (repeatable)")
    t.add_argument("--jobs", type=int, default=2, help="processes to simulate in")
    t.set_defaults(fn=cmd_twin)

    for name, fn, hlp in (
        ("validate", cmd_validate, "check a recording tree through the gate, as the workflow does before its DAG"),
        ("seal", cmd_seal, "re-seal: record the current sealed test set (after a deliberate change to it)"),
    ):
        v = sub.add_parser(name, help=hlp)
        v.add_argument("raw_dir", nargs="?", help="recording tree (default: config raw_data.dir)")
        v.add_argument("--config", default="config.yaml", help="limits (gate:, raw_data:) and budget")
        v.add_argument("--budget", choices=["paper", "quick", "smoke"], help="budget of the run (split sizes)")
        v.add_argument("--source", choices=["rig", "twin"], default="rig" if name == "validate" else None,
                       help="plan from index.csv (rig) or from the budget (twin); seal: default from config")
        v.add_argument("--exclude", action="append", help="leave this group out, as raw_data.exclude (repeatable)")
        v.set_defaults(fn=fn)

    au = sub.add_parser("audit", help="which recordings fed RESULT, which never did, and whether it is stale")
    au.add_argument("result")
    au.add_argument("--root", default=".")
    au.add_argument("--json", action="store_true")
    _config_args(au)
    au.set_defaults(fn=cmd_audit)

    cs = sub.add_parser("check-separation", help="prove the evidence-set separation (docs/design.md section 3)")
    _config_args(cs)
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

    d = sub.add_parser("deploy", help="run one open-loop trial of the deployment manifest on the servos")
    d.add_argument("--manifest", default="results/deployment/manifest.json")
    d.add_argument("--port", help="serial port of the servo bus, e.g. /dev/ttyUSB0")
    d.add_argument("--baud", type=int, help="default: the manifest's (1000000)")
    tg = d.add_mutually_exclusive_group()
    tg.add_argument("--target", help="x,y,z of the target in the base frame (m)")
    tg.add_argument("--target-from-mocap", help="JSON file {target_m: [x, y, z]} exported by the mocap system")
    d.add_argument("--placement", type=int,
                   help="which of the manifest's placements (1-based) the block stands at: recorded for Table II, "
                        "and the target unless --target or --target-from-mocap gives the measured one")
    d.add_argument("--out", help="recording tree to write the trial into (groups/<id>/, aborted/)")
    d.add_argument("--group-id", default="dep_0001")
    d.add_argument("--dry-run", action="store_true", help="print the commands and goal schedule, open no port")
    d.add_argument("--yes", action="store_true", help="do not ask before moving the arm")
    d.set_defaults(fn=cmd_deploy)

    di = sub.add_parser("deploy-index", help="index the deployment trials recorded in the lab (Table II, Fig. 7)")
    di.add_argument("--raw", help="the deployment recording tree (default: <raw_data.dir>/deployment)")
    di.add_argument("--config", default="config.yaml", help="the workflow's config (its gate and raw_data.dir)")
    di.add_argument("--planned", type=int, help="trials planned (default: those found); Table II's denominator")
    di.set_defaults(fn=cmd_deploy_index)

    cl = sub.add_parser("claims", help="the claims ledger: every paper number beside ours, by section and status")
    cl.add_argument("--section", action="append", help="only this paper section, e.g. III-B (repeatable)")
    cl.add_argument("--status", action="append", choices=["agrees", "differs", "not measured", "no paper value"],
                    help="only claims with this status (repeatable)")
    cl.add_argument("--root", default=".")
    cl.add_argument("--ledger", default="results/tables/claims.csv")
    cl.set_defaults(fn=cmd_claims)

    cr = sub.add_parser("crate", help="write the run as a Workflow Run RO-Crate (or --verify it against results/)")
    cr.add_argument("--out", default="results/crate/")
    cr.add_argument("--root", default=".")
    cr.add_argument("--verify", action="store_true", help="check that every result file is in it with its sha256")
    cr.set_defaults(fn=cmd_crate)

    rc = sub.add_parser("report-check", help="open the HTML report in headless Chromium: every figure and table shown")
    rc.add_argument("html", nargs="?", default="results/report.html")
    rc.add_argument("--screenshot", default="results/report.png")
    rc.set_defaults(fn=cmd_report_check)

    a = p.parse_args(argv)
    return a.fn(a)


if __name__ == "__main__":
    sys.exit(main())

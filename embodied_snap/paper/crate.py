"""The run as a Workflow Run RO-Crate (Provenance Run Crate profile), from the provenance records.

The Snakefile is the main entity (a ComputationalWorkflow written in Snakemake, its rule files as
parts); every rule is a HowToStep of it, whose tool is the rule's script; every recorded job is a
CreateAction (instrument: the rule's tool; object: its input files; result: its output files, each
File with the sha256 its record holds) with a ControlAction tying it to its step; an OrganizeAction
is the engine's run, a CreateAction of the workflow its whole: the config as object, every result
as result. Software versions come from the records. Files are addressed by their path relative to
the workflow root (`raw_data/groups/...`, `results/...`): the crate describes the run's files in
place and copies none, so its data entities resolve against the repository, two levels above
results/crate/ (`..` in ids would not do: RO-Crate canonicalises them inside the crate, and
`report/x.rst` and `results/report/x.rst` would become one). PROV-JSON (results/lineage/prov.json)
stays beside it.
"""

from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import unquote

from ..files import sha256
from ..lineage.records import AFTER_RUN, CONFIG_DIR, RECORDS_DIR, load_records, record_path

PROFILES = {
    "https://w3id.org/ro/wfrun/process/0.5": "Process Run Crate",
    "https://w3id.org/ro/wfrun/workflow/0.5": "Workflow Run Crate",
    "https://w3id.org/ro/wfrun/provenance/0.5": "Provenance Run Crate",
    "https://w3id.org/workflowhub/workflow-ro-crate/1.0": "Workflow RO-Crate",
}
DEFAULT_OUT = "results/crate"
# The crate job's own record is written after the crate.
OWN_RECORD = record_path("crate", {}).as_posix()


def result_files(root=".", out: str = DEFAULT_OUT, own_record: str | None = OWN_RECORD) -> list[str]:
    """Every file under results/ the crate must list: job outputs, provenance records and configs;
    not the crate's own folder or record, the report, nor Snakemake's directory markers."""
    root = Path(root)
    out = Path(out).as_posix().rstrip("/") + "/"
    files = []
    for f in sorted((root / "results").rglob("*")):
        p = f.relative_to(root).as_posix()
        if (f.is_file() and not p.startswith(out) and p != own_record and p not in AFTER_RUN
                and f.name != ".snakemake_timestamp" and not f.name.startswith(".")):
            files.append(p)
    return files


def build(root=".", out: str = DEFAULT_OUT, own_record: str | None = OWN_RECORD, may_read=None):
    """The crate (rocrate.ROCrate) of the recorded run in `root`, to be written to `out`.
    `may_read(path)`: whether a result file no record hashed may be read to hash it (the crate
    job: only what it declares); one it may not is listed without a sha256."""
    from rocrate.model.contextentity import ContextEntity
    from rocrate.rocrate import ROCrate

    root = Path(root)
    rel = str  # ids are paths relative to the workflow root (see above)
    records = {r["_record"]: r for r in load_records(root).values()}
    crate = ROCrate()
    crate.name = "embodied-snap: a recorded run"
    crate.description = "Every job of one Snakemake run of embodied-snap, from raw recordings to figures and tables."
    crate.root_dataset["conformsTo"] = [{"@id": u} for u in PROFILES]
    for u, name in PROFILES.items():
        crate.add(ContextEntity(crate, u, properties={"@type": "CreativeWork", "name": name, "version": u[-3:]}))

    files: dict[str, object] = {}

    def file(path: str, digest: str | None = None, size: int | None = None):
        if path not in files:
            full = root / path
            props = {"name": path}
            if digest is None and full.is_file():
                digest, size = sha256(full), full.stat().st_size
            if digest:
                props["sha256"] = digest
            if size is not None:
                props["contentSize"] = str(size)
            files[path] = crate.add_file(dest_path=rel(path), properties=props)
        return files[path]

    smk_parts = [file(p.relative_to(root).as_posix()) for p in sorted((root / "rules").glob("*.smk"))]
    wf = crate.add_workflow(dest_path=rel("Snakefile"), main=True, lang="snakemake",
                            properties={"name": "embodied-snap Snakefile", "hasPart": smk_parts})
    files["Snakefile"] = wf
    # Software: the engine and every pinned package the records name, with the versions that ran.
    versions: dict[str, str] = {}
    for r in records.values():
        versions.update({k: v for k, v in (r.get("packages") or {}).items() if v})
        if r.get("python"):
            versions["python"] = r["python"]
    soft = {k: crate.add(ContextEntity(crate, f"#software-{k}", properties={
        "@type": "SoftwareApplication", "name": k, "softwareVersion": v})) for k, v in sorted(versions.items())}
    wf["softwareRequirements"] = list(soft.values())
    engine = soft.get("snakemake")

    steps, tools = {}, {}
    for pos, rule in enumerate(sorted({r["rule"] for r in records.values()})):
        script = next((e["path"] for r in records.values() if r["rule"] == rule
                       for e in r.get("code", []) if e["path"].startswith("workflow_scripts/")), None)
        tools[rule] = crate.add(ContextEntity(crate, f"#tool-{rule}", properties={
            "@type": "SoftwareApplication", "name": rule,
            **({"url": rel(script)} if script else {})}))
        steps[rule] = crate.add(ContextEntity(crate, f"#step-{rule}", properties={
            "@type": "HowToStep", "name": rule, "position": str(pos), "workExample": tools[rule]}))
    wf["step"] = list(steps.values())

    controls, results = [], []
    for key, r in sorted(records.items()):
        job = key.removeprefix(RECORDS_DIR + "/").removesuffix(".json")
        ins = [file(e["path"], e.get("sha256"), e.get("bytes")) for e in r.get("inputs", []) + r.get("code", [])]
        outs = [file(e["path"], e.get("sha256"), e.get("bytes")) for e in r.get("outputs", [])]
        results += outs
        act = crate.add_action(tools[r["rule"]], identifier=f"#job-{job}", object=ins, result=outs, properties={
            "name": f"job {job}", "startTime": r.get("started"), "endTime": r.get("finished"),
            "description": f"rule {r['rule']}, wildcards {r.get('wildcards', {})}, record {key}",
        })
        act["subjectOf"] = file(key)  # the provenance record itself
        controls.append(crate.add(ContextEntity(crate, f"#control-{job}", properties={
            "@type": "ControlAction", "name": f"orchestrate {job}", "instrument": steps[r["rule"]], "object": act})))
    configs = [file(p.relative_to(root).as_posix()) for p in sorted((root / CONFIG_DIR).glob("*.json"))]
    run = crate.add_action(wf, identifier="#run", object=configs, result=list({id(x): x for x in results}.values()),
                           properties={"name": "the workflow run"})
    crate.add(ContextEntity(crate, "#engine-run", properties={
        "@type": "OrganizeAction", "name": "Snakemake run", "object": controls, "result": run,
        **({"instrument": engine} if engine else {})}))
    for p in result_files(root, out, own_record):  # anything else under results/ (configs, records)
        # A file no record names yet, and not declared, is a job's still running beside the crate
        # (the robustness variants': `snakemake all` rewrites the crate after them): never read.
        readable = may_read is None or p.startswith(RECORDS_DIR + "/") or may_read(p)
        file(p) if readable else file(p, "")
    return crate


def write(root=".", out: str = DEFAULT_OUT, own_record: str | None = OWN_RECORD, may_read=None) -> Path:
    out_dir = Path(root) / out
    crate = build(root, out, own_record, may_read)
    out_dir.mkdir(parents=True, exist_ok=True)
    crate.metadata.write(out_dir)
    return out_dir / "ro-crate-metadata.json"


def _path(out: str, eid: str) -> str:
    """A File's id as a path relative to the workflow root (what the ids are)."""
    return os.path.normpath(unquote(eid)).replace(os.sep, "/")  # rocrate quotes '=' and the like


def upstream(root=".", out: str = DEFAULT_OUT, path: str = "") -> set[str]:
    """Every file the crate's job actions lead back to from `path` (result <- action <- object ...)."""
    from rocrate.rocrate import ROCrate

    crate = ROCrate(Path(root) / out)
    made_by: dict[str, list] = {}
    for e in crate.get_entities():
        if e.type == "CreateAction" and e.id.startswith("#job-"):
            for r in e.get("result") or []:
                made_by.setdefault(_path(out, r.id), []).append(e)
    seen, todo = set(), [path]
    while todo:
        p = todo.pop()
        for act in made_by.get(p, []):
            for o in act.get("object") or []:
                q = _path(out, o.id)
                if q not in seen:
                    seen.add(q)
                    todo.append(q)
    return seen


def verify(root=".", out: str = DEFAULT_OUT, own_record: str | None = OWN_RECORD) -> list[str]:
    """One line per file under results/ that the crate does not list exactly once with the sha256
    the file has now (a result changed after the crate was written)."""
    from rocrate.rocrate import ROCrate

    root = Path(root)
    crate = ROCrate(root / out)
    seen: dict[str, list] = {}
    for e in crate.get_entities():
        if "File" in (e.type if isinstance(e.type, list) else [e.type]):
            p = _path(out, e.id)
            seen.setdefault(p, []).append(e.get("sha256"))
    bad = []
    for p in result_files(root, out, own_record):
        got = seen.get(p, [])
        if len(got) != 1:
            bad.append(f"{p}: listed {len(got)} times in {out}/ro-crate-metadata.json (rule: every result once)")
        elif got[0] != sha256(root / p):
            bad.append(f"{p}: sha256 differs from the crate's (rule: the crate describes the results as they are)")
    return bad

"""The whole DAG on the smoke budget, in a copy of the repository: fresh run, exact reruns after a
changed recording or an edited module, audit, separation, and a broken recording stopping cleanly.

The tests in this module share one smoke run and are ordered: the destructive ones come last.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from embodied_snap.lineage.dag import build_dag, rule_table

from importprobe import loaded_by_scripts

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench"))  # bench/timeline.py reads Snakemake's logs
from timeline import logged_job  # noqa: E402

COPY = ["Snakefile", "config.yaml", "rules", "workflow_scripts", "schemas", "envs", "profiles",
        "reference", "report", "embodied_snap", "docs"]
SMOKE = ["--config", "budget=smoke"]
BIN = Path(sys.executable).parent

# The suite's workflow runs are background work at the lowest priority, so the real-time tests on the
# other worker (the lab's sync-reads, the control loop) are scheduled first. It narrows the problem but
# does not end it: the lab tests have still failed beside the other worker's in-process tests.
BACKGROUND = ["nice", "-n", "19"]

pytestmark = pytest.mark.slow


def run(cmd, cwd, check=True, **env):
    """`cmd` in `cwd` with this interpreter's tools and `cwd`'s package first, in the background;
    `env`: more variables. check: raise with the output's tail when it fails."""
    env = {**os.environ, "PYTHONPATH": str(cwd), "PATH": f"{BIN}:{os.environ['PATH']}", **env}
    r = subprocess.run([*BACKGROUND, *cmd], cwd=cwd, env=env, capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed:\n{r.stdout[-4000:]}\n{r.stderr[-4000:]}")
    return r


def snakemake(cwd, *args, check=True):
    return run(["snakemake", "--cores", "2", *args, *SMOKE], cwd, check)


def dry_jobs(cwd, *targets) -> list[tuple[str, str]]:
    """(rule, wildcards) of every job a dry run would execute, sorted."""
    out = snakemake(cwd, "-n", *targets).stdout
    jobs = []
    for line in out.splitlines():
        m = re.match(r"^(?:rule|checkpoint) ([\w-]+):", line.strip())
        if m:
            jobs.append(list(logged_job(m.group(1))))
        m = re.match(r"^wildcards: (.*)$", line.strip())
        if m and jobs:
            jobs[-1][1] = m.group(1)
    return sorted((r, w) for r, w in jobs)


def digest_tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def wf(smoke_run):
    """This module's copy of the session's smoke run (conftest.smoke_run)."""
    return smoke_run


def test_fresh_run_builds_figures_and_lineage(wf):
    figs = sorted(p.name for p in (wf / "results/figures").iterdir())
    assert "fig0_data_overview.pdf" in figs and "fig0_data_overview.png" in figs
    index = pd.read_csv(wf / "raw_data/index.csv")
    assert len(index) == 48 and index.group_id.is_unique
    sep = json.loads((wf / "results/lineage/separation.json").read_text())
    assert sep["ok"] and not sep["violations"]
    # The DAG proof sees the jobs that read recordings directly (raw_of): while every shard's files
    # waited on its checkpoint, the proof's own DAG held placeholders there and it saw none.
    assert sep["checked"]["dag_direct_readers"] > 0
    assert "twin_phenomena" in sep["sources"]["release_mode"]["uses"]
    prov = json.loads((wf / "results/lineage/prov.json").read_text())
    assert "entity" in prov and "activity" in prov
    split = pd.read_csv(wf / "results/splits/split.csv")
    assert split.role.value_counts().to_dict() == {"train": 9, "validation": 3, "sealed": 2}
    # the sealed set, recorded beside the recordings when first split
    rec = json.loads((wf / "raw_data/sealed.json").read_text())["groups"]
    assert sorted(rec) == sorted(split[split.role == "sealed"].group_id)


def test_every_job_reading_recordings_waits_for_their_validation(wf):
    """With the simulated rig the recordings are written during the run, by a rule per shard: every
    job that reads one starts only after its shard's validate_shard job, the gate's checks (directly
    or through a job that depends on it; docs/data.md, "The gate")."""
    nodes = build_dag(wf, config_overrides={"budget": "smoke"}, targets=("all", "robustness"))
    raw = "raw_data/groups/"
    checked_by = {f: i for i, n in enumerate(nodes) if n["rule"] == "validate_shard"
                  for f in n["input"] if f.startswith(raw)}
    up: dict[int, set[int]] = {}
    for i, n in enumerate(nodes):
        for k in n["down"]:
            up.setdefault(k, set()).add(i)

    def before(i):
        seen, todo = set(), [i]
        while todo:
            for k in up.get(todo.pop(), ()):
                if k not in seen:
                    seen.add(k)
                    todo.append(k)
        return seen

    # the checks themselves: a shard's, and the sealed set's against its record
    readers = [i for i, n in enumerate(nodes) if n["rule"] not in {"validate_shard", "validate_sealed"}
               and any(f.startswith(raw) for f in n["input"])]
    assert {nodes[i]["rule"] for i in readers} >= {"resample_shard", "twin_phenomena", "dynamics_hold"}
    early = sorted({(nodes[i]["rule"], f.split("/")[2]) for i in readers for f in nodes[i]["input"]
                    if f.startswith(raw) and checked_by[f] not in before(i)})
    assert early == []


def test_runs_searched_in_lockstep_keep_the_claims_inside_the_seed_spread(wf, tmp_path):
    """config policy.batch_runs (the GPU's schedule, here on CPU): the benchmark's runs in one job,
    every generation of all of them one batch of rollouts. On a copy of the smoke run only the
    searches and what reads them rerun, and each architecture's mean reward and attachment lie
    within the seed spread (sd) of the one-job-per-run claims; each run is the same search (its
    own generator), so only the batch's floating-point rounding can move them."""
    d = tmp_path / "wf"
    shutil.copytree(wf, d, symlinks=True)
    (d / "batch.yaml").write_text("policy:\n  batch_runs: true\n")
    batch = ["--configfile", "config.yaml", "batch.yaml"]
    jobs = {r for r, _ in dry_jobs(d, "results/policy/claims.csv", *batch)}
    assert jobs == {"policy_search_lockstep", "policy_evaluate", "policy_summary", "table_policy_claims"}
    snakemake(d, "results/policy/claims.csv", *batch)
    # the claims' numbers, as results/policy/claims.csv reads them from the summary
    summaries = [json.loads((t / "results/policy/summary.json").read_text()) for t in (wf, d)]
    runs = [json.loads(p.read_text()) for p in sorted((d / "results/policy/runs").glob("*.json"))]
    archs = sorted({r["arch"] for r in runs})
    assert len(runs) == len(list((wf / "results/policy/runs").glob("*.json"))) and len(archs) > 1
    spread = [a for a in archs if summaries[0]["reward"][a]["n"] > 1]  # an sd needs two seeds
    assert spread
    for a in spread:
        for what in ("reward", "attachment_report"):
            m = [s[what][a]["mean"] for s in summaries]
            sd = max(s[what][a]["sd"] for s in summaries)
            assert abs(m[0] - m[1]) <= sd, (a, what, m, sd)


def test_robustness_variants_extend_the_benchmark(wf):
    """The variants' benchmark is the policy stage's; the double budget continues each run (its first
    generations are the run's own) and the half budget stops it halfway."""
    s = json.loads((wf / "results/robustness/summary.json").read_text())
    bench = json.loads((wf / "results/policy/summary.json").read_text())
    assert list(s) == ["benchmark", "uniform", "half", "double"]
    assert s["benchmark"]["reward"] == bench["reward"]
    g = s["benchmark"]["generations"]
    assert s["double"]["generations"] == 2 * g and s["half"]["generations"] == round(g / 2)
    run = json.loads((wf / "results/policy/runs/shared_seed0.json").read_text())
    longer = json.loads((wf / "results/robustness/double/runs/shared_seed0.json").read_text())
    assert longer["curve"][:g] == run["curve"] and len(longer["curve"]) == 2 * g
    claims = pd.read_csv(wf / "results/robustness/variants.csv")
    assert set(claims.variant) == set(s) and (claims.claim_id.str.endswith("ranking_reward_holds")).sum() == 4


def test_starting_points_extend_the_benchmark_and_the_landscape_bounds_it(wf):
    """The benchmark's start is the policy stage's runs; every configured start is read by the fixed
    rule; the per-target optimum is at least as good as every policy on its targets (it is searched
    on them), and both its repeats are kept."""
    s = json.loads((wf / "results/sensitivity/summary.json").read_text())
    bench = json.loads((wf / "results/policy/summary.json").read_text())
    cfg = yaml.safe_load((wf / "config.yaml").read_text())["policy"]
    assert list(s) == ["zero-0.1", *cfg["sensitivity"]]
    assert s["zero-0.1"]["reward"] == bench["reward"]
    for name, start in cfg["sensitivity"].items():
        assert s[name]["archs"] == [a for a in s["zero-0.1"]["archs"] if a in start["archs"]]
        assert s[name]["reproduced"] in (True, False)
    starts = pd.read_csv(wf / "results/sensitivity/starts.csv")
    assert (starts.claim_id.str.endswith(".reproduced")).sum() == len(s)
    opt = pd.read_parquet(wf / "results/landscape/optimum.parquet")
    assert {"reward_repeat0", "reward_repeat1"} <= set(opt.columns)
    assert np.allclose(opt.reward, opt[["reward_repeat0", "reward_repeat1"]].max(axis=1), atol=1e-6)
    table = pd.read_csv(wf / "results/landscape/architectures.csv")
    assert set(table.arch) == set(bench["archs"]) | {"fixed"}
    assert (table.optimum_reward >= table.searched_reward_mean).all()


def test_nothing_to_do_after_a_run(wf):
    assert dry_jobs(wf, "all") == []


def test_the_runs_the_ablation_and_deployment_read_are_searched_first(wf):
    """The ablation and the deployment read only the shared architecture's runs (found here from
    the DAG), so those searches go first (policy_search's `priority`) and the two stages can run
    beside the other searches: in the fresh run no other search started before the last of them.
    All searches become ready together (with the ensemble), so the order is the scheduler's."""
    sys.path.insert(0, str(REPO / "bench"))
    from timeline import jobs

    out = snakemake(wf, "-n", "--forceall", "results/deployment/manifest.json").stdout
    read = set(re.findall(r"rule policy_search:(?:\n\s+\S.*)*?\n\s+wildcards: (arch=\w+, seed=\d+)", out))
    assert read and all(w.startswith("arch=shared,") for w in read)
    first = jobs(sorted((wf / ".snakemake/log").glob("*.snakemake.log"))[0])  # the fresh run's log
    starts = {True: [], False: []}
    for j in first:
        if j["rule"] == "policy_search":
            starts[j["wildcards"] in read].append(j["start"])
    assert starts[True] and starts[False]
    assert max(starts[True]) <= min(starts[False]), starts


def test_every_search_starts_before_the_short_jobs_that_wait_for_it(wf):
    """Longest first: all searches are ready together, and a core that frees takes a search
    (search_priority) before an evaluation of a run that is not the shared architecture's (ready as
    its search ends), so the short jobs fill the cores beside the last searches instead of delaying
    them (in the paper run before this, the last search started after 34 s of evaluations and GRU
    validations)."""
    sys.path.insert(0, str(REPO / "bench"))
    from timeline import jobs

    fresh = jobs(sorted((wf / ".snakemake/log").glob("*.snakemake.log"))[0])
    search = [j["start"] for j in fresh if j["rule"] == "policy_search"]
    short = [j["start"] for j in fresh
             if j["rule"] == "policy_evaluate" and not j["wildcards"].startswith("arch=shared,")]
    assert search and short
    assert max(search) <= min(short), (max(search), sorted(short))


def test_priorities_are_exactly_on_the_jobs_that_must_not_wait(wf):
    """An allow list derived from the fresh run's own log (every job's inputs, outputs and
    priority). A job of `all` has the first priority if and only if it reads recordings (hundreds
    of inputs, which Snakemake re-examines while a job waits) or the policy runs it writes or reads
    are the shared architecture's alone (those searches and evaluations, the ablation, the
    deployment manifest and the trials that run it: they go before the other searches). The other
    searches, and they alone, have the second: the long jobs start before the short ones (longest
    first). The other figures have the third: the longest of the short jobs. The separation proof
    also reads only shared runs, but it waits on every claims table anyway; the robustness
    variants are not in `all`."""
    sys.path.insert(0, str(REPO / "bench"))
    from timeline import jobs as logged
    from timeline import stages

    stage = stages(wf)
    fresh = sorted((wf / ".snakemake/log").glob("*.snakemake.log"))[0]
    jobs = [j for j in logged(fresh) if stage[j["rule"]] != "robustness"]

    def first(j):
        runs = set(re.findall(r"results/policy/runs/(\w+)_seed\d+\.json", " ".join(j["input"] + j["output"])))
        reads_raw = any(f.startswith("raw_data/") for f in j["input"])
        # records trials with the manifest of the shared runs
        deploys = "results/deployment/manifest.json" in j["input"] and any(
            f.startswith("raw_data/") for f in j["output"])
        return reads_raw or deploys or (runs == {"shared"} and not any(f.endswith("claims.csv") for f in j["input"]))

    def expected(j):
        if first(j):
            return 3
        if j["rule"] == "policy_search":
            return 2
        return 1 if any(f.startswith("results/figs/") for f in j["output"]) else 0

    assert {expected(j) for j in jobs} == {0, 1, 2, 3}
    assert all(j["priority"] == expected(j) for j in jobs), [
        (j["rule"], j["priority"]) for j in jobs if j["priority"] != expected(j)]


def test_audit_of_train_windows_names_train_groups_only(wf):
    r = run([str(BIN / "esnap"), "audit", "results/splits/windows_train.npz", "--json"], wf)
    rep = json.loads(r.stdout)
    split = pd.read_csv(wf / "results/splits/split.csv")
    train = set(split[split.role == "train"].group_id)
    sets = rep["evidence_sets"]
    assert {g for s in sets.values() for g in s["fed"]} == train
    assert not rep["stale"]
    never = {name for name, s in sets.items() if not s["fed"]}
    assert never == {"attachment", "delay_sweep", "servo_calibration", "release_mode", "held_base"}


def test_each_number_is_fed_by_the_recordings_of_its_own_fit(wf):
    """Issue 28: every ledger row has its own artifact:key; the III-A calibration numbers are fed by
    the calibration bursts alone, the IV-A sealed numbers by sealed dynamics groups alone, Table II's
    by the deployment trials alone."""
    from embodied_snap.characterize.claims import OURS

    rows = {r["claim_id"]: r for r in pd.read_csv(wf / "results/tables/claims.csv", dtype=str,
                                                  keep_default_na=False).to_dict("records")}
    assert all(r["source"] and all(re.fullmatch(r"results/\S+\.json:\S+", s) for s in r["source"].split())
               for r in rows.values())
    assert all(r["artifact"] == " ".join(dict.fromkeys(s.split(":")[0] for s in r["source"].split()))
               for r in rows.values())
    n = pd.read_csv(wf / "raw_data/index.csv").evidence_set.value_counts()
    cal = [c for c, (fit, _) in OURS.items() if fit in ("kinematics", "servo")]
    assert len(cal) == 12
    for c in cal:
        assert rows[c]["fed_by"] == f"servo_calibration {n['servo_calibration']}/{n['servo_calibration']}", c
    split = pd.read_csv(wf / "results/splits/split.csv")
    sealed = set(split[split.role == "sealed"].group_id)
    r = json.loads(run([str(BIN / "esnap"), "audit", "sealed_gru_tip_mm_0p3", "--json"], wf).stdout)
    used = r["lineage"]["evidence_sets"]["dynamics"]["used"]
    assert list(r["lineage"]["evidence_sets"]) == ["dynamics"] and set(used) <= sealed and used and not r["stale"]
    dep = pd.read_csv(wf / "raw_data/deployment/index.csv")
    for c in ("preload_reached", "fast_snap", "peak_speed_median_mps", "retrieved"):
        assert rows[c]["fed_by"] == f"deployment {len(dep)}/{len(dep)}", c
    out = run([str(BIN / "esnap"), "audit", "tendon_travel_per_tick_um"], wf).stdout
    assert out.startswith("CLAIM tendon_travel_per_tick_um  (III-A:") and "stale: no" in out
    k = n["servo_calibration"]
    assert re.search(rf"^fed by {k} raw group\(s\) from 1 evidence set\(s\):\n  servo_calibration +{k}/{k} ", out, re.M)


def test_changing_one_attachment_recording_reruns_only_its_dependents(wf):
    f = wf / "raw_data/groups/att_0003/mocap.parquet"
    df = pd.read_parquet(f)
    df.loc[10, "tip_x"] += 1e-4  # a re-recorded trial: one sample moved by 0.1 mm
    f.chmod(0o644)
    df.to_parquet(f, index=False)
    jobs = dry_jobs(wf, "results/figures")
    assert jobs == sorted(
        [
            ("validate_shard", "shard=attachment-00"),
            ("characterize_attachment", ""),
            ("fig_limits", ""),
            ("fig_system", ""),  # Fig. 1b's strike is att_0001, of the same shard's validation record
            ("raw_manifest", ""),
            ("fig_data_overview", ""),
            ("table_characterize_claims", ""),
            ("check_separation", ""),
            ("figures", ""),
        ]
    )
    r = run([str(BIN / "esnap"), "audit", "results/figures/fig0_data_overview.pdf"], wf, check=False)
    assert r.returncode == 1 and "stale" in r.stdout.lower()
    snakemake(wf, "all")
    assert dry_jobs(wf, "all") == []


def dry_reasons(cwd, *targets) -> dict[tuple[str, str], str]:
    """{(rule, wildcards): reason} of every job a dry run would execute."""
    out = snakemake(cwd, "-n", *targets).stdout
    jobs, key = {}, None
    for line in out.splitlines():
        line = line.strip()
        m = re.match(r"^(?:local)?(?:rule|checkpoint) ([\w-]+):", line)
        if m:
            key = list(logged_job(m.group(1)))
        elif key and line.startswith("wildcards: "):
            key[1] = line.removeprefix("wildcards: ")
        elif key and line.startswith("reason: "):
            jobs[tuple(key)] = line.removeprefix("reason: ")
            key = None
    return jobs


@pytest.mark.parametrize(
    "module", ["embodied_snap/acquisition/programs.py", "embodied_snap/rawformat.py", "embodied_snap/figures/gates.py"]
)
def test_editing_a_module_reruns_exactly_the_rules_whose_scripts_load_it(wf, module):
    """Which rules' scripts load the module is found by Python's import machinery; the dry run must
    rerun exactly those for the edit, and every other job only because an input is rebuilt."""
    loads = loaded_by_scripts(wf)
    table = rule_table(wf, config_overrides={"budget": "smoke"})
    # of the rules the smoke run ran: a rule that lost a ruleorder has no job (dynamics_train beside
    # dynamics_train_seeds)
    sys.path.insert(0, str(REPO / "bench"))
    from timeline import jobs as logged

    ran = {j["rule"] for log in (wf / ".snakemake/log").glob("*.snakemake.log") for j in logged(log)}
    # a rule per shard (twin_acquire_<shard>) counts as its rule, as the log's jobs do
    expected = {logged_job(r)[0] for r, d in table.items() if d["script"] and module in loads[d["script"]]} & ran
    assert expected
    m = wf / module
    keep, st = m.read_bytes(), m.stat()
    m.write_bytes(keep + b"\n# edited\n")
    try:
        jobs = dry_reasons(wf, "all", "robustness")  # what the smoke run built
    finally:
        m.write_bytes(keep)
        os.utime(m, ns=(st.st_atime_ns, st.st_mtime_ns))
    edited = {rule for (rule, _), why in jobs.items() if "Updated input files:" in why and module in why}
    listed = {rule for rule, _ in jobs}
    if "twin_acquire" in expected:
        # The edit reruns the acquisition, so every job downstream of a shard reruns and Snakemake
        # gives it that reason alone: each rule that loads the module reruns, for the edit or so.
        # Snakemake 9.27 does not look at the own inputs of a job below one that reruns when the
        # edge between them is ancient (dag.update_needrun masks it): the index, its check and the
        # sealed set's check rerun in the run after (docs/lineage.md).
        assert "twin_acquire" in edited and edited <= expected
        assert expected - listed <= {"twin_index", "validate_index", "validate_sealed"}
    else:
        assert edited == expected
    others = {k: why for k, why in jobs.items() if k[0] not in expected}
    assert all(why.startswith("Input files updated by another job") for why in others.values()), others
    assert dry_jobs(wf, "all") == []


def test_an_undeclared_read_of_sealed_windows_fails_the_job(wf):
    """A script that computes the persistence errors on the sealed windows without declaring them
    is stopped by its own provenance check, with one line, before it vouches for anything."""
    script = wf / "workflow_scripts/dynamics_persistence.py"
    keep, st = script.read_bytes(), script.stat()
    script.write_bytes(
        keep.replace(b"load_windows(snakemake.input.validation)", b'load_windows("results/splits/windows_sealed.npz")')
    )
    try:
        r = snakemake(wf, "results/dynamics/validation/persistence.json", check=False)
        assert r.returncode != 0
        lines = sorted({ln for ln in (r.stdout + r.stderr).splitlines() if ln.startswith("error:")})
        assert lines == [
            "error: results/splits/windows_sealed.npz: read by rule dynamics_persistence but not among "
            "its declared inputs (rule: a job reads only what it declares)"
        ]
        assert not (wf / "results/provenance/dynamics_persistence/_.json").exists()
    finally:
        script.write_bytes(keep)
        os.utime(script, ns=(st.st_atime_ns, st.st_mtime_ns))
    snakemake(wf, "all")
    assert dry_jobs(wf, "all") == []


@contextmanager
def sealed_group_in_train(wf):
    """An injected leak: the first sealed group of the split moved to train (yields its id); the
    split's bytes are restored afterwards."""
    split = wf / "results/splits/split.csv"
    keep = split.read_bytes()
    df = pd.read_csv(split)
    sealed = df[df.role == "sealed"].group_id.iloc[0]
    df.loc[df.group_id == sealed, "role"] = "train"
    df.to_csv(split, index=False)
    try:
        yield sealed
    finally:
        split.write_bytes(keep)


def test_injected_leak_is_caught(wf):
    with sealed_group_in_train(wf) as sealed:
        r = run([str(BIN / "esnap"), "check-separation", "--no-static"], wf, check=False)
        assert r.returncode == 1 and sealed in r.stdout


def test_broken_recording_stops_with_one_line_and_touches_nothing(wf):
    """The gate decides while the plan is read: no job runs, no file under results/ changes."""
    f = wf / "raw_data/groups/att_0005/mocap.parquet"
    good, st = f.read_bytes(), f.stat()
    before = digest_tree(wf / "results")
    f.chmod(0o644)
    f.write_bytes(good[: len(good) // 2])  # a truncated parquet
    try:
        r = snakemake(wf, "results/figures", check=False)
        assert r.returncode != 0
        lines = [l for l in (r.stdout + r.stderr).splitlines() if l.startswith("error:")]
        assert len(lines) == 1 and "att_0005" in lines[0], r.stderr[-3000:]
        assert "mocap.parquet" in lines[0] and "(rule: readable parquet)" in lines[0]
        assert digest_tree(wf / "results") == before
    finally:
        f.write_bytes(good)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert dry_jobs(wf, "all") == []  # the same bytes and time again: nothing to redo


def test_relabelled_index_row_stops_the_simulated_rig_too(wf):
    idx = wf / "raw_data/index.csv"
    good, st = idx.read_bytes(), idx.stat()
    before = digest_tree(wf / "results")
    idx.chmod(0o644)
    idx.write_text(good.decode().replace("dyn_0007,dynamics,sealed", "dyn_0007,dynamics,free_space"))
    try:
        r = snakemake(wf, "all", check=False)
        lines = [l for l in (r.stdout + r.stderr).splitlines() if l.startswith("error:")]
        assert r.returncode != 0 and len(lines) == 1, r.stderr[-3000:]
        assert "group dyn_0007: category 'free_space' but the plan says 'sealed'" in lines[0]
        assert digest_tree(wf / "results") == before
    finally:
        idx.write_bytes(good)
        os.utime(idx, ns=(st.st_atime_ns, st.st_mtime_ns))

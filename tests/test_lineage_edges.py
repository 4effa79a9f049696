"""The lineage checks at their edges (issue 27, item 4), in-process: what a job's watch sees, what
check_declared lets through and what it refuses, and the policy's held-out fallback. The end-to-end
versions (a Snakemake job, a subprocess) are tests/test_lineage_reads.py and tests/test_watch.py;
these are the fast ones mutation testing runs."""

from __future__ import annotations

import json
import os
import sys
import types

import pytest
from snakemake.iocontainers import Namedlist

from embodied_snap.lineage import policy
from embodied_snap.lineage import records as R

# --- Namedlists as written into a record -------------------------------------------------------------


def test_named_keeps_names_and_puts_positional_entries_under_underscore():
    assert R._named(None) == {}
    assert R._named([]) == {}
    assert R._named(["a.parquet", "b.parquet"]) == {"_": ["a.parquet", "b.parquet"]}
    assert R._named(Namedlist(["x", "y"])) == {"_": ["x", "y"]}
    named = Namedlist(fromdict={"frames": "results/f.parquet", "meta": ["m1.json", "m2.json"]})
    assert R._named(named) == {"frames": "results/f.parquet", "meta": ["m1.json", "m2.json"]}
    assert R._named({"a": 1}) == {"a": 1}


def test_flat_flattens_nested_lists_to_strings():
    assert R._flat(None) == []
    assert R._flat(["a", ["b", ("c", ["d"])], 3]) == ["a", "b", "c", "d", "3"]


# --- the watch: reads under the root, data only ---------------------------------------------------


@pytest.fixture
def fresh_watch(monkeypatch):
    """The watch's module state as in a new process (the hook itself, once added, stays)."""
    monkeypatch.setattr(R, "_opened", None)
    yield
    R._opened = None


def test_watch_sees_data_reads_under_root_only(tmp_path, fresh_watch):
    data = [f"results/d{i:02d}/x.parquet" for i in range(12)] + [f"raw_data/g{i}.json" for i in range(6)]
    skipped = ([f"logs/r{i}.log" for i in range(4)] + [f"benchmarks/b{i}.tsv" for i in range(3)]
               + [f".snakemake/s{i}" for i in range(3)] + ["results/.hidden/y", "workflow_scripts/s.py",
                                                           "embodied_snap/io.py"])
    for rel in data + skipped + ["written.txt"]:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x")
    outside = tmp_path.parent / f"{tmp_path.name}-outside.txt"
    outside.write_text("x")
    R._watch()
    assert R._hooked is True and R._opened == set()
    for rel in skipped + data:
        (tmp_path / rel).read_text()
    outside.read_text()
    (tmp_path / "written.txt").write_text("y")  # opened for writing: not a read
    with open(tmp_path / "appended.txt", "a") as f:
        f.write("z")
    assert R._stop_watching(tmp_path) == sorted(data)
    assert R._opened is None
    (tmp_path / data[0]).read_text()  # after the watch: not collected
    assert R._opened is None


def test_a_watch_already_running_keeps_what_it_saw(tmp_path, fresh_watch):
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "a").write_text("x")
    R._watch()
    (tmp_path / "results" / "a").read_text()
    R._watch()  # a second start (the job's `tracked` after the start-up hook's watch)
    assert R._stop_watching(tmp_path) == ["results/a"]


def test_the_audit_hook_is_added_once(monkeypatch, fresh_watch):
    added = []
    monkeypatch.setattr(R, "_hooked", False)
    monkeypatch.setattr(R.sys, "addaudithook", added.append)
    R._watch()
    R._watch()
    assert added == [R._audit] and R._hooked is True


# --- check_declared / check_watched -----------------------------------------------------------------


def test_declared_reads_pass_and_undeclared_reads_under_results_or_raw_fail():
    ok = dict(declared=["results/frames.parquet", "results/windows/", "raw_data/dyn_0001",
                        "embodied_snap/io.py"], raw="raw_data")
    R.check_declared("r", reads=["results/frames.parquet", "results/windows/train.npz",
                                 "raw_data/dyn_0001/meta.json",  # under a declared directory (no slash)
                                 "results/provenance/other.json",  # records: metadata
                                 "config.yaml", "reference/paper_values.yaml"],  # not data
                     modules=["embodied_snap/io.py"], **ok)
    for bad in ("results/windowsX/train.npz", "results/frames.parquet.bak", "raw_data/dyn_0002/meta.json"):
        with pytest.raises(R.UndeclaredInput, match=rf"^{bad}: read by rule r but not among its declared "
                           r"inputs \(rule: a job reads only what it declares\)$"):
            R.check_declared("r", reads=["config.yaml", "results/provenance/x.json", bad], modules=[], **ok)


def test_a_declared_directory_with_a_trailing_slash_covers_its_files():
    R.check_declared("r", ["results/w/"], ["results/w/a.npz"], [], "raw_data")
    R.check_declared("r", ["results/w"], ["results/w/a.npz"], [], "raw_data")
    with pytest.raises(R.UndeclaredInput):
        R.check_declared("r", ["results/w"], ["results/wx/a.npz"], [], "raw_data")


def test_the_raw_directory_is_the_configured_one():
    R.check_declared("r", [], ["raw_data/x.json"], [], "lab/raw")  # not data of this run
    with pytest.raises(R.UndeclaredInput, match=r"^lab/raw/x\.json: read by rule r"):
        R.check_declared("r", [], ["lab/raw/x.json"], [], "lab/raw")


def test_an_undeclared_module_fails_with_its_rule():
    R.check_declared("r", ["embodied_snap/io.py"], [], ["embodied_snap/io.py"], "raw_data")
    with pytest.raises(R.UndeclaredInput, match=r"^embodied_snap/fit\.py: loaded by rule fit_x but not among its "
                       r"code inputs \(rule: code inputs are the script's imports, lineage/imports\.py\)$"):
        R.check_declared("fit_x", ["embodied_snap/io.py"], [], ["embodied_snap/io.py", "embodied_snap/fit.py"],
                         "raw_data")


def test_check_watched_fails_a_job_whose_watch_did_not_begin_at_its_start(monkeypatch):
    monkeypatch.setattr(R, "_from_start", False)
    R.check_watched("r")  # not a job (pytest): nothing to say
    main = types.ModuleType("__main__")
    main.snakemake = object()
    monkeypatch.setitem(sys.modules, "__main__", main)
    with pytest.raises(R.UndeclaredInput, match=r"^workflow_scripts/fit\.py: run by rule r without the watch from "
                       r"its start \(rule: a job's reads are watched from its interpreter's start by "
                       r"embodied_snap/lineage/startup/sitecustomize\.py, which the workflow puts on its jobs' "
                       r"PYTHONPATH, docs/lineage\.md\)$"):
        R.check_watched("r", "workflow_scripts/fit.py")
    monkeypatch.setattr(R, "_from_start", True)
    R.check_watched("r")


def test_the_start_up_hook_starts_the_watch_and_says_so(monkeypatch, fresh_watch):
    monkeypatch.setattr(R, "_from_start", False)
    R.watch_from_start()
    assert R._from_start is True and R._opened == set()


def test_the_job_environment_puts_the_hook_first_once():
    hook = str(R.STARTUP)
    assert (R.STARTUP / "sitecustomize.py").is_file()
    assert R.job_environment({}) == {"PYTHONPATH": hook}
    env = R.job_environment({"PYTHONPATH": os.pathsep.join(["/a", "", "/b"])})
    assert env == {"PYTHONPATH": os.pathsep.join([hook, "/a", "/b"])}
    assert R.job_environment(env) == env  # the Snakefile read twice in one process


def test_in_job_is_snakemakes_preamble_in_main(monkeypatch):
    assert R._in_job() is False  # pytest's __main__ has no `snakemake`
    main = types.ModuleType("__main__")
    main.snakemake = object()
    monkeypatch.setitem(sys.modules, "__main__", main)
    assert R._in_job() is True
    monkeypatch.setitem(sys.modules, "__main__", types.ModuleType("__main__"))
    assert R._in_job() is False


# --- policy -----------------------------------------------------------------------------------


def test_policy_entry_names_are_the_rule_before_the_first_parenthesis():
    assert policy._names("windows(role=train)") == "windows"
    assert policy._names("fit(model=a(b))") == "fit"
    assert policy._names("characterize_servo") == "characterize_servo"


@pytest.mark.parametrize("role, evidence_set, held", [
    ("validation", "dynamics", True), ("sealed", "dynamics", True), ("train", "dynamics", False),
    (None, "delay_sweep", True), (None, "deployment", True), (None, "attachment", False),
    (None, "servo_calibration", False), ("train", "delay_sweep", False), (None, "no_such_set", False),
])
def test_held_out_by_role_then_by_evidence_set(role, evidence_set, held):
    assert policy.held_out(role, evidence_set) is held


# --- the audit hook itself ---------------------------------------------------------------------


def test_audit_collects_read_only_opens_only(fresh_watch):
    R._audit("open", ("/d/before", "r", os.O_RDONLY))  # no watch: nothing, and no error
    R._opened = set()
    R._audit("open", ("/d/r", "r", os.O_RDONLY))
    R._audit("open", ("/d/rb", "rb", os.O_RDONLY))
    R._audit("open", (b"/d/bytes", "r", os.O_RDONLY))
    R._audit("open", ("/d/os-open", None, os.O_RDONLY))  # os.open: flags, no mode
    R._audit("open", ("/d/mode-wins", "r", os.O_WRONLY))  # a mode, when given, decides
    for name, mode, flags in (("w", "w", os.O_WRONLY), ("a", "a", os.O_WRONLY), ("x", "x", os.O_WRONLY),
                              ("rplus", "r+", os.O_RDWR), ("os-w", None, os.O_WRONLY | os.O_CREAT),
                              ("os-rw", None, os.O_RDWR), ("mode-w-flags-r", "w", os.O_RDONLY)):
        R._audit("open", (f"/d/{name}", mode, flags))
    R._audit("open", (5, "r", os.O_RDONLY))  # an fd: seen when it was opened
    R._audit("open", (None, "r", os.O_RDONLY))
    R._audit("os.listdir", ("/d/listed", "r", os.O_RDONLY))  # not an open
    R._audit("open", ("/d/short",))  # malformed: ignored, never raised
    assert R._opened == {"/d/r", "/d/rb", "/d/bytes", "/d/os-open", "/d/mode-wins"}


def test_a_declared_directory_is_stripped_of_slashes_only():
    with pytest.raises(R.UndeclaredInput, match=r"^results/FI/a: read by rule r"):
        R.check_declared("r", ["results/FIX"], ["results/FI/a"], [], "raw_data")
    R.check_declared("r", ["results/FIX//"], ["results/FIX/a"], [], "raw_data")


# --- load_records ----------------------------------------------------------------------------------


def _rec(root, rule, outs, finished):
    p = root / R.RECORDS_DIR / rule / f"{finished}.json"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps({"rule": rule, "finished": finished, "outputs": [{"path": o} for o in outs]}))
    return p


def test_load_records_skips_configs_and_reports_what_is_not_a_record(tmp_path, monkeypatch):
    cfg = tmp_path / R.CONFIG_DIR / "abc.json"
    cfg.parent.mkdir(parents=True)
    cfg.write_text(json.dumps({"budget": "smoke"}))  # a config: neither a record nor an error
    _rec(tmp_path, "a_rule", ["results/a.parquet"], "2026-12-01T10:00:00")
    _rec(tmp_path, "z_rule", ["results/z.parquet", "results/shared.txt"], "2026-12-01T11:00:00")
    _rec(tmp_path, "m_rule", ["results/shared.txt"], "2026-12-01T09:00:00")  # finished earlier: loses
    bad = tmp_path / R.RECORDS_DIR / "q_rule" / "x.json"
    bad.parent.mkdir()
    bad.write_text(json.dumps({"outputs": [{"path": "results/q"}]}))  # no rule
    (tmp_path / R.RECORDS_DIR / "q_rule" / "y.json").write_text("[1, 2]")  # not an object
    (tmp_path / R.RECORDS_DIR / "q_rule" / "z.json").write_text("{half")
    errors = []
    out = R.load_records(tmp_path, errors)
    assert sorted(out) == ["results/a.parquet", "results/shared.txt", "results/z.parquet"]
    assert out["results/shared.txt"]["rule"] == "z_rule"
    assert out["results/a.parquet"]["_record"] == "results/provenance/a_rule/2026-12-01T10:00:00.json"
    assert errors[:2] == [("results/provenance/q_rule/x.json", "ValueError: not a provenance record"),
                          ("results/provenance/q_rule/y.json", "ValueError: not a provenance record")]
    assert len(errors) == 3 and errors[2][0] == "results/provenance/q_rule/z.json"
    monkeypatch.chdir(tmp_path)
    assert sorted(R.load_records()) == sorted(out)  # the root defaults to the working directory


def test_load_records_a_record_gone_after_the_listing_is_missing_not_unreadable(tmp_path):
    # a job beside the reader reruns: Snakemake removed its record between the glob and the read
    # (the changed-recording rerun's check_separation met fig_limits' record so). A dangling link is
    # listed and cannot be opened, as such a record is.
    _rec(tmp_path, "a_rule", ["results/a.parquet"], "2026-12-01T10:00:00")
    gone = tmp_path / R.RECORDS_DIR / "fig_rule" / "_.json"
    gone.parent.mkdir()
    gone.symlink_to(tmp_path / "nowhere.json")
    (tmp_path / R.RECORDS_DIR / "q_rule").mkdir()
    (tmp_path / R.RECORDS_DIR / "q_rule" / "_.json").mkdir()  # a folder: unreadable, still reported
    errors = []
    assert sorted(R.load_records(tmp_path, errors)) == ["results/a.parquet"]
    assert [e[0] for e in errors] == ["results/provenance/q_rule/_.json"]


def test_load_records_the_later_finished_wins_whatever_the_file_order(tmp_path):
    # b_rule sorts before y_rule but finished later: it keeps the shared output
    _rec(tmp_path, "b_rule", ["results/shared.txt"], "2026-12-01T11:00:00")
    _rec(tmp_path, "y_rule", ["results/shared.txt"], "2026-12-01T09:00:00")
    # the same finishing time: the one read last (sorted path) wins
    _rec(tmp_path, "c_rule", ["results/tie.txt"], "2026-12-01T10:00:00")
    _rec(tmp_path, "d_rule", ["results/tie.txt"], "2026-12-01T10:00:00")
    # a record without `finished` loses to one with it, read before or after
    _rec(tmp_path, "e_rule", ["results/nofin.txt"], "2026-12-01T10:00:00")
    p = tmp_path / R.RECORDS_DIR / "f_rule" / "x.json"
    p.parent.mkdir()
    p.write_text(json.dumps({"rule": "f_rule", "outputs": [{"path": "results/nofin.txt"}]}))
    p = tmp_path / R.RECORDS_DIR / "h_rule" / "x.json"  # read first, no `finished`: loses to i_rule
    p.parent.mkdir()
    p.write_text(json.dumps({"rule": "h_rule", "outputs": [{"path": "results/nofin2.txt"}]}))
    _rec(tmp_path, "i_rule", ["results/nofin2.txt"], "2026-12-01T08:00:00")
    p = tmp_path / R.RECORDS_DIR / "g_rule" / "x.json"
    p.parent.mkdir()
    p.write_text(json.dumps({"rule": "g_rule"}))  # no outputs at all: fine, claims nothing
    out = R.load_records(tmp_path)
    assert out["results/shared.txt"]["rule"] == "b_rule"
    assert out["results/tie.txt"]["rule"] == "d_rule"
    assert out["results/nofin.txt"]["rule"] == "e_rule" and out["results/nofin2.txt"]["rule"] == "i_rule"
    assert sorted(out) == ["results/nofin.txt", "results/nofin2.txt", "results/shared.txt", "results/tie.txt"]


def test_paths_relative_to_the_root(tmp_path):
    assert R._rel(tmp_path / "results" / "a.parquet", tmp_path) == "results/a.parquet"
    assert R._rel("./results/a.parquet", tmp_path) == "results/a.parquet"
    assert R._rel("results/a.parquet", tmp_path) == "results/a.parquet"
    assert R._rel(str(tmp_path / "raw_data" / "x.json"), tmp_path) == "raw_data/x.json"


def test_code_inputs_are_package_modules_and_workflow_scripts():
    assert R.is_code("embodied_snap/io.py") and R.is_code("workflow_scripts/fit.py")
    assert not R.is_code("results/embodied_snap/x") and not R.is_code("config.yaml")


@pytest.mark.parametrize("config, raw", [(None, "raw_data"), ({}, "raw_data"), ({"raw_data": None}, "raw_data"),
                                         ({"raw_data": {}}, "raw_data"), ({"raw_data": {"dir": "lab/raw/"}}, "lab/raw"),
                                         ({"raw_data": {"dir": "./a//b"}}, "a/b")])
def test_the_raw_directory_a_config_names(config, raw):
    assert R.raw_dir_of(config) == raw


def test_policy_labels_and_may_feed():
    assert policy.label("fit", {}) == "fit"
    assert policy.label("windows", {"role": "train", "a": 1}) == "windows(a=1,role=train)"
    assert policy.may_feed("train", "windows", {"role": "train"})
    assert not policy.may_feed("validation", "windows", {"role": "train"})
    assert policy.may_feed("validation", "windows", {"role": "validation"})
    assert policy.may_feed("validation", "dynamics_validate", {})
    assert not policy.may_feed("delay_sweep", "characterize_servo", {})
    assert policy.may_feed("delay_sweep", "characterize_delay_sweep", {})
    assert policy.may_feed("delay_sweep", "check_separation", {})  # bookkeeping reads everything
    assert policy.may_feed("delay_sweep", "validate_shard", {})  # where a shard's recordings enter
    assert policy.may_feed("no_policy_row", "dynamics_train", {})  # judged by its split roles


@pytest.mark.parametrize("switches", [{}, {"policy": {"batch_runs": True}}, {"dynamics": {"seeds_in_one_job": False}}])
def test_every_rule_of_every_schedule_is_named_by_the_policy(switches):
    """The separation proof refuses a rule the policy does not name, so each rule a config switch
    brings in (the searches in lockstep, a job per GRU seed) must be named, or a run with it fails."""
    from pathlib import Path

    from embodied_snap.lineage.dag import rule_table
    from embodied_snap.lineage.records import instance

    table = rule_table(Path(__file__).resolve().parents[1], config_overrides={"budget": "smoke", **switches})
    # a rule per shard (twin_acquire_<shard>) is named as its rule (records.instance)
    assert {instance(r, {})[0] for r in table} - policy.named_rules() == set()


def test_a_rule_per_shard_is_read_as_its_rule_with_the_shard():
    """rules/acquire.smk names each shard's rule per_shard_name(rule, shard); the lineage reads it back
    as the rule with its `shard` wildcard, and every other rule as it is."""
    from embodied_snap.lineage.records import PER_SHARD, instance, per_shard_name

    for shard in ("dynamics_train-01", "attachment-00"):
        assert instance(per_shard_name("twin_acquire", shard), {}) == ("twin_acquire", {"shard": shard})
    assert PER_SHARD == ("twin_acquire",)
    assert instance("twin_index", {}) == ("twin_index", {})
    assert instance("validate_shard", {"shard": "attachment-00"}) == ("validate_shard", {"shard": "attachment-00"})
    assert instance("twin_acquire", {}) == ("twin_acquire", {})  # not a rule per shard

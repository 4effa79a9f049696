"""The cluster path without a cluster: the SLURM profile's resources come from measurements (and
`esnap resources` reproduces them), its rules exist, a GPU is asked for exactly when the config
trains on cuda, and the code falls back to CPU when there is none. `make cluster-test` runs the
real thing (docs/cluster.md)."""

import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
import yaml

from embodied_snap import resources as R
from embodied_snap import runconfig
from embodied_snap.cli import main
from embodied_snap.dynamics import device as D
from embodied_snap.lineage.dag import rule_table
from embodied_snap.lineage.records import instance, per_shard_name
from embodied_snap.plan import load_plan

REPO = Path(__file__).resolve().parents[1]
PROFILE = REPO / "profiles/slurm/config.yaml"
# Copies of a paper-budget run's benchmark files: for each benchmarked rule, the files holding its
# longest wall time and its largest RSS (the maxima set-resources is computed from).
BENCH = REPO / "tests/data/benchmarks"


@pytest.fixture(scope="module")
def table():
    return rule_table(REPO)


def test_profile_set_resources_reproduced_from_benchmarks(capsys):
    assert main(["resources", "--benchmarks", str(BENCH), "--profile", str(PROFILE), "--root", str(REPO),
                 "--check"]) == 0, capsys.readouterr().err


def test_resources_rewrite_only_the_generated_part(tmp_path, table):
    prof = tmp_path / "config.yaml"
    head = PROFILE.read_text().split(R.MARKER)[0]
    prof.write_text(head + R.MARKER + "\nset-resources:\n  dynamics_train: {mem_mb: 1}\n")
    assert main(["resources", "--benchmarks", str(BENCH), "--profile", str(prof), "--root", str(REPO),
                 "--check"]) == 1
    assert main(["resources", "--benchmarks", str(BENCH), "--profile", str(prof), "--root", str(REPO)]) == 0
    assert prof.read_text() == PROFILE.read_text()


def test_margins():
    # 438 s, 690 MB (the paper run's GRU training): 2x the time, 1.5x the memory in 100 MB steps
    assert R.rule_resources(438.03, 690.12, 3) == dict(mem_mb=1100, runtime=15, cpus_per_task=3)
    # seconds-long jobs get the floors
    assert R.rule_resources(2.7, 200.0, 1) == dict(mem_mb=R.MEM_MIN, runtime=R.RUNTIME_MIN, cpus_per_task=1)


def test_every_benchmarked_rule_has_resources_and_threads(table):
    """Measured, or listed as not measured: exactly the benchmarked rules the run left no file for;
    a rule per shard (the acquisition) takes default-resources, its names follow the budget."""
    res = yaml.safe_load(PROFILE.read_text())["set-resources"]
    missing = R.not_measured(PROFILE.read_text())
    per_shard = {r for r in table if instance(r, {})[0] != r}
    # one acquisition rule per shard of the paper budget's plan
    assert per_shard == {per_shard_name("twin_acquire", s) for s in load_plan(runconfig.load()).shard}
    assert not per_shard & (set(res) | set(missing))
    assert set(res) | set(missing) | per_shard == {r for r, t in table.items() if t["benchmark"]}
    unmeasured = R.measure(BENCH, {r: t["benchmark"] for r, t in table.items() if t["benchmark"]})[1]
    assert missing == [r for r in unmeasured if r not in per_shard]
    for r, v in res.items():
        assert v["cpus_per_task"] == table[r]["threads"], r


def test_bad_benchmark_trees(tmp_path, table):
    patterns = {r: t["benchmark"] for r, t in table.items() if t["benchmark"]}
    shutil.copytree(BENCH, tmp_path / "b")
    for f in (tmp_path / "b/dynamics").glob("*.tsv"):
        f.unlink()
    measured, missing = R.measure(tmp_path / "b", patterns)
    assert "dynamics_train" in missing and "dynamics_train" not in measured
    shutil.copytree(BENCH, tmp_path / "c")
    (tmp_path / "c/old_rule.tsv").write_text((BENCH / "twin_phenomena.tsv").read_text())
    with pytest.raises(R.ResourceError, match="old_rule.tsv: matches no rule"):
        R.measure(tmp_path / "c", patterns)
    (tmp_path / "c/old_rule.tsv").write_text("not a benchmark\n")
    with pytest.raises(R.ResourceError, match="not a Snakemake benchmark"):
        R.read_benchmark(tmp_path / "c/old_rule.tsv")


def test_profile_groups_and_rules_exist(table):
    prof = yaml.safe_load(PROFILE.read_text())
    assert prof["executor"] == "slurm" and prof["slurm-status-command"] == "squeue"
    assert set(prof["groups"]) <= set(table)
    assert set(prof.get("group-components", {})) <= set(prof["groups"].values())


@pytest.mark.parametrize("training", ["cuda", "cpu", "auto"])
@pytest.mark.parametrize("rollouts", ["cuda", "cpu", "auto"])
def test_jobs_ask_for_a_gpu_only_where_their_device_is_cuda(training, rollouts):
    """dynamics.device: the training job; policy.device: every job whose code loads the ensemble's
    rollouts (derived from the scripts' imports, so a new rollout job cannot be left out). auto is
    decided on the node: it asks for none."""
    t = rule_table(REPO, config_overrides={"budget": "smoke", "dynamics": {"device": training},
                                           "policy": {"device": rollouts}})
    rolls = {r for r, v in t.items() if any(c.endswith("embodied_snap/dynamics/rollout.py") for c in v["code"] or [])}
    assert len(rolls) > 10 and "policy_search" in rolls and "dynamics_train" not in rolls
    # the training jobs: a job per seed, or every seed in one (config dynamics.seeds_in_one_job)
    fits = {r for r, v in t.items() if v["script"] == "dynamics_train.py"}
    assert fits == {"dynamics_train", "dynamics_train_seeds"}
    want = (fits if training == "cuda" else set()) | (rolls if rollouts == "cuda" else set())
    assert {r for r, v in t.items() if v["resources"].get("gpu")} == want


class _Res(dict):
    __getattr__ = dict.__getitem__


@pytest.mark.parametrize("gpu", [1, 0])
def test_plugin_turns_gpu_into_a_gpu_request(gpu):
    from snakemake_executor_plugin_slurm.submit_string import get_submit_command
    from snakemake_executor_plugin_slurm.utils import set_gres_string

    job = SimpleNamespace(resources=_Res(gpu=gpu, mem_mb=1100, runtime=15, cpus_per_task=1), threads=1,
                          name="dynamics_train", is_group=lambda: False)
    params = dict(run_uuid="u", slurm_logfile="l", comment_str="c", account="", partition="", workdir="w")
    call = get_submit_command(job, params) + set_gres_string(job)
    assert ("--gpus=1" in call) == bool(gpu)  # SLURM's short form of --gres=gpu:1
    assert "--mem 1100" in call and "-t 15" in call and "--cpus-per-task=1" in call


def test_cuda_without_gpu_falls_back_to_cpu_with_one_line(monkeypatch):
    lines = []
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert D.resolve("cuda", lines.append) == "cpu"
    assert len(lines) == 1 and "running on cpu" in lines[0]
    assert D.resolve("cpu", lines.append) == "cpu" and len(lines) == 1
    with pytest.raises(ValueError, match="dynamics.device"):
        D.resolve("tpu")
    assert D.resolve("auto", lines.append) == "cpu" and len(lines) == 1  # auto says nothing
    with pytest.raises(ValueError, match="policy.device: 'gpu' is not one of auto, cpu, cuda"):
        D.resolve("gpu", key="policy.device")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch, "use_deterministic_algorithms", lambda on: lines.append(("deterministic", on)))
    assert D.resolve("cuda", lines.append) == "cuda" and D.resolve("auto", lines.append) == "cuda"
    assert lines[1:] == [("deterministic", True)] * 2

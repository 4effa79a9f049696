"""The one module that uses Snakemake's private API (lineage/dag.py): if a Snakemake upgrade
moves what it reads, these fail here, loudly, rather than the separation proof passing on an
empty graph."""

from embodied_snap.lineage.dag import build_dag, rule_table

SNAKEFILE = '''
rule all:
    input: "c.txt"

rule a:
    output: "a_{x}.txt"
    shell: "touch {output}"

rule c:
    input: expand("a_{x}.txt", x=(1, 2)), code=["m.py"]
    output: "c.txt"
    benchmark: "benchmarks/c.tsv"
    threads: 3
    resources: gpu=1, mem_mb=lambda wc: 5
    script: "s.py"
'''


def test_build_dag_reads_jobs_and_edges(tmp_path):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    (tmp_path / "m.py").write_text("")
    nodes = build_dag(tmp_path)
    by = {(n["rule"], tuple(sorted(n["wildcards"].items()))): n for n in nodes}
    assert set(by) == {("all", ()), ("a", (("x", "1"),)), ("a", (("x", "2"),)), ("c", ())}
    c = by[("c", ())]
    assert c["input"] == ["a_1.txt", "a_2.txt", "m.py"] and c["output"] == ["c.txt"]
    for x in ("1", "2"):
        assert [nodes[k]["rule"] for k in by[("a", (("x", x),))]["down"]] == ["c"]
    assert [nodes[k]["rule"] for k in c["down"]] == ["all"]


def test_rule_table_reads_scripts_and_code(tmp_path):
    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    t = rule_table(tmp_path)
    assert {k: t["c"][k] for k in ("script", "code", "benchmark", "threads")} == {
        "script": "s.py", "code": ["m.py"], "benchmark": r"benchmarks/c\.tsv$", "threads": 3}
    assert t["c"]["resources"]["gpu"] == 1 and "mem_mb" not in t["c"]["resources"]  # a function: per job
    assert {k: t["a"][k] for k in ("script", "code", "benchmark", "threads")} == {
        "script": None, "code": None, "benchmark": None, "threads": 1}


def test_a_file_rewritten_beside_the_build_is_read_again(tmp_path, monkeypatch):
    """Inside a run, a job beside the separation check may delete an output while Snakemake reads
    the tree ('... although it existed before'): the build is tried again; any other error is not."""
    import pytest
    from snakemake.exceptions import WorkflowError
    from snakemake.workflow import Workflow

    from embodied_snap.lineage import dag

    (tmp_path / "Snakefile").write_text(SNAKEFILE)
    (tmp_path / "m.py").write_text("")
    real, calls = Workflow._build_dag, []

    def flaky(self, *a, **k):
        calls.append(1)
        if len(calls) == 1:
            raise WorkflowError("Unable to obtain modification time of file a_1.txt although it existed before.")
        return real(self, *a, **k)

    monkeypatch.setattr(Workflow, "_build_dag", flaky)
    monkeypatch.setattr(dag.time, "sleep", lambda s: None)
    assert len(build_dag(tmp_path)) == 4 and len(calls) == 2

    def broken(self, *a, **k):
        calls.append(1)
        raise WorkflowError("MissingInputException")

    monkeypatch.setattr(Workflow, "_build_dag", broken)
    with pytest.raises(WorkflowError, match="MissingInput"):
        build_dag(tmp_path)
    assert len(calls) == 3

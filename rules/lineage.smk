# Lineage (docs/design.md section 5): the separation proof runs before any table or figure is published.


rule check_separation_dag:
    """docs/design.md section 3, proved on the Snakemake DAG: its edges follow from the workflow, its
    config and the plan (index.csv, the split), never from a recording's values, so a changed
    recording reuses this half of the proof."""
    input:
        workflow=["Snakefile", *sorted(glob.glob("rules/*.smk")), "config.yaml"],
        index=raw_index(),
        # the Snakefile, parsed to build the DAG, runs the gate over every recording and checks
        # the sealed set against its record: read, but no recording's values move the DAG
        sealed_record=ancient(f"{RAW}/{sealed.RECORD}"),
        raw=ancient_raw_of(),
        valid=ancient(validated()),
        split="results/splits/split.csv",
        deployment_index=[f"{DEPLOYMENT_RAW}/index.csv"] if DEPLOYED else [],
        code=imports("check_separation_dag"),
    output:
        "results/lineage/separation_dag.json",
    log:
        "logs/check_separation_dag.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        config=lambda wc: {k: config[k] for k in ("budget", "raw_data")},
    script:
        "../workflow_scripts/check_separation_dag.py"


rule check_separation:
    """docs/design.md section 3, proved on the DAG (check_separation_dag) and on the provenance
    records."""
    input:
        dag="results/lineage/separation_dag.json",
        index=raw_index(),
        split="results/splits/split.csv",
        windows=expand("results/splits/windows_{role}.npz", role=ROLE_SHARDS),
        manifest="results/raw/manifest.json",
        # every simulated target set (the separation policy's list): proved pairwise disjoint
        targets=list(SEPARATION.TARGET_FILES),
        # the claims tables come after every model, policy and target set: all records exist
        claims=claims_tables,
        # the deployment recordings and the manifest they ran: nothing upstream changed after export
        deployment_index=[f"{DEPLOYMENT_RAW}/index.csv"] if DEPLOYED else [],
        deployment_groups=[f"{DEPLOYMENT_RAW}/groups"] if DEPLOYED else [],
        deployment_manifest=f"{DEPLOYMENT_DIR}/manifest.json",
        manifest_inputs=MANIFEST_FILES,
        code=imports("check_separation"),
    output:
        "results/lineage/separation.json",
    log:
        "logs/check_separation.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        config=lambda wc: {k: config[k] for k in ("budget", "raw_data")},
    script:
        "../workflow_scripts/check_separation.py"


rule prov_export:
    """The run's provenance as W3C PROV-JSON."""
    input:
        "results/lineage/separation.json",
        "results/figures",
        index=raw_index(),
        split="results/splits/split.csv",
        code=imports("prov_export"),
    output:
        "results/lineage/prov.json",
    log:
        "logs/prov_export.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=lambda wc, input: os.path.dirname(input.index),
    script:
        "../workflow_scripts/prov_export.py"

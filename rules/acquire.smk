# Acquisition on the simulated rig (docs/design.md section 6): raw_data/ is written here, group by group.
# Recordings are source data: the protocol writes a group's files once, read-only, and never
# overwrites them; a changed recording reruns only what reads it.


# A rule per shard: the plan names each shard's groups before anything runs, so its recordings
# are the rule's declared outputs and every job that reads one waits on exactly that rule
# (docs/design.md, "Scheduling"). The lineage reads each as the job
# twin_acquire(shard=...).
for shard, gids in SHARDS.items():

    rule:
        name:
            per_shard_name("twin_acquire", shard)
        input:
            code=imports("twin_acquire"),
        output:
            recordings=group_files(gids),
            acquired=ACQUIRED.format(shard=shard),
        log:
            f"logs/twin_acquire/{shard}.log",
        benchmark:
            f"benchmarks/twin_acquire/{shard}.tsv"
        conda:
            "../envs/esnap.yaml"
        params:
            groups=select(shard=shard).to_dict("records"),
            raw=lambda wc, output: raw_dir_of(output.recordings[0]),
            seed=config["seed"],
            protocol=protocol_params(*protocol.ACQUISITION),
            dt=config["twin"]["dt"],
            hold=config["twin"]["held_base"],
        script:
            "../workflow_scripts/twin_acquire.py"


rule twin_index:
    input:
        acquired=ancient(expand(ACQUIRED, shard=SHARDS)),
        code=imports("twin_index"),
    output:
        protected(f"{RAW}/index.csv"),
    log:
        "logs/twin_index.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/twin_index.py"


rule twin_truth:
    input:
        code=imports("twin_truth"),
    output:
        protected(f"{RAW}/twin_truth.json"),
    log:
        "logs/twin_truth.log",
    conda:
        "../envs/esnap.yaml"
    params:
        seed=config["seed"],
        sessions=config["sessions"],
        # it runs the acquisition's calibration programs (acquisition/programs.py)
        protocol=protocol_params(*protocol.ACQUISITION),
    script:
        "../workflow_scripts/twin_truth.py"


PHENOMENA_SETS = ["release_mode", "delay_sweep", "attachment"]


rule twin_phenomena:
    """What the simulated rig shows, read from its recordings as the pipeline reads them."""
    input:
        raw=raw_of(evidence_set=PHENOMENA_SETS),
        valid=validated(evidence_set=PHENOMENA_SETS),
        code=imports("twin_phenomena"),
    output:
        "results/twin/phenomena.json",
    log:
        "logs/twin_phenomena.log",
    benchmark:
        "benchmarks/twin_phenomena.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        protocol=protocol_params("sampling", "primitive", "rig", "thresholds"),
        groups=select(evidence_set=PHENOMENA_SETS)[
            ["group_id", "evidence_set", "category", "session"]
        ].to_dict("records"),
    script:
        "../workflow_scripts/twin_phenomena.py"


rule twin_validation:
    """The one reader of the twin's ground truth: phenomena beside the paper's hardware values, and
    the fitted lever ratios and servo constants beside the true ones."""
    input:
        truth=f"{RAW}/twin_truth.json",
        phenomena="results/twin/phenomena.json",
        kinematics="results/characterize/kinematics.json",
        servo="results/characterize/servo.json",
        reference="reference/paper_values.yaml",
        code=imports("twin_validation"),
    output:
        "results/twin/validation.json",
    log:
        "logs/twin_validation.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/twin_validation.py"


rule twin_render:
    """Fig. 1a: the arm rendered offscreen from the simulated rig's MuJoCo model."""
    input:
        code=imports("twin_render"),
    output:
        "results/twin/render.png",
    log:
        "logs/twin_render.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/twin_render.py"

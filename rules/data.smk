# Raw recordings -> validated manifest -> 50 Hz state/command series -> group split and windows
# (docs/design.md section 4, steps 2-3; paper section IV-A).


rule validate_shard:
    """Every recording of a shard against the rig format (one-line error naming file, group, rule)."""
    input:
        raw=shard_raw,
        index=ancient(raw_index()),
        code=imports("validate_shard"),
    output:
        "results/raw/shards/{shard}.json",
    log:
        "logs/validate_shard/{shard}.log",
    benchmark:
        "benchmarks/validate_shard/{shard}.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        groups=lambda wc: SHARDS[wc.shard],
        gate=asdict(LIMITS),
    script:
        "../workflow_scripts/validate_shard.py"


rule validate_index:
    """index.csv against the group folders: unique ids, known sets, no row without files or files without row."""
    input:
        index=raw_index(),
        shards=ancient(expand("results/raw/shards/{shard}.json", shard=SHARDS)),
        code=imports("validate_index"),
    output:
        "results/raw/index_check.json",
    log:
        "logs/validate_index.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        gate=asdict(LIMITS),
    script:
        "../workflow_scripts/validate_index.py"


rule raw_manifest:
    """One manifest of the raw tree: sha256 per file, group by group."""
    input:
        index="results/raw/index_check.json",
        shards=expand("results/raw/shards/{shard}.json", shard=SHARDS),
        code=imports("raw_manifest"),
    output:
        "results/raw/manifest.json",
    log:
        "logs/raw_manifest.log",
    conda:
        "../envs/esnap.yaml"
    params:
        excluded=EXCLUDED,
    script:
        "../workflow_scripts/raw_manifest.py"


rule resample_shard:
    """Each group on its own to the 50 Hz grid: state x_t (21) and command u_t (9)."""
    input:
        raw=shard_raw,
        valid="results/raw/shards/{shard}.json",
        code=imports("resample_shard"),
    output:
        RESAMPLED_SHARD,
    log:
        "logs/resample_shard/{shard}.log",
    benchmark:
        "benchmarks/resample_shard/{shard}.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=lambda wc: SHARDS[wc.shard],
        protocol=protocol_params("sampling"),
    script:
        "../workflow_scripts/resample_shard.py"


rule validate_sealed:
    """The sealed test set, recorded once when first split (ids, categories, sha256 per file) beside
    the recordings, so deleting results/ keeps it; every later plan is checked against it.
    """
    input:
        raw=ancient_raw_of(role="sealed"),
        code=imports("validate_sealed"),
    output:
        f"{RAW}/{sealed.RECORD}",
    log:
        "logs/validate_sealed.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=lambda wc, output: os.path.dirname(output[0]),
        plan=select(role="sealed")[
            ["group_id", "evidence_set", "category", "role"]
        ].to_dict("records"),
    script:
        "../workflow_scripts/validate_sealed.py"


rule split:
    """440/78/20 by acquisition group, seeded; depends on the group list alone."""
    input:
        sealed=ancient(f"{RAW}/{sealed.RECORD}"),
        code=imports("split"),
    output:
        "results/splits/split.csv",
    log:
        "logs/split.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        split=select(evidence_set="dynamics")[
            ["group_id", "category", "session", "role"]
        ].to_dict("records"),
        seed=config["seed"],
    script:
        "../workflow_scripts/split.py"


rule windows:
    """Windows of one split (20-step history, 5-step look-ahead, 25-step horizon), from that split's
    shards only: the DAG itself shows what each model saw."""
    input:
        shards=lambda wc: expand(RESAMPLED_SHARD, shard=ROLE_SHARDS[wc.role]),
        split="results/splits/split.csv",
        code=imports("windows"),
    output:
        "results/splits/windows_{role}.npz",
    log:
        "logs/windows/{role}.log",
    benchmark:
        "benchmarks/windows/{role}.tsv"
    conda:
        "../envs/esnap.yaml"
    params:
        protocol=protocol_params("windows"),
    script:
        "../workflow_scripts/windows.py"

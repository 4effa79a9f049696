# Release-rule ablation, bend point and pre-release perturbation (paper IV-B, V-A, V-B, Fig. 6,
# Table I "Release targets"; docs/ablation.md). Offsets are fitted on the offset targets only; the
# release-evaluation targets are read only by ablation_rules (esnap check-separation).

ABLATION_DIR = "results/ablation"
ABLATION_CONFIG = config["ablation"]
ABLATION_BUDGET = BUDGET["ablation"]
# The trigger thresholds; the grid step, anchor and timing set are the simulator's (the protocol's).
TRIGGERS = dict(
    s1_rate_deg_s=ABLATION_CONFIG["s1_rate_deg_s"],
    tip_speed_mps=ABLATION_CONFIG["tip_speed_mps"],
)


rule ablation_targets:
    """Offset and release-evaluation targets in target families, each set from its own seed."""
    input:
        workspace=f"{POLICY_DIR}/workspace.json",
        code=imports("ablation_targets"),
    output:
        offset=f"{ABLATION_DIR}/targets_offset.parquet",
        release=f"{ABLATION_DIR}/targets_release.parquet",
    log:
        "logs/ablation/targets.log",
    conda:
        "../envs/esnap.yaml"
    params:
        sizes=dict(
            offset=ABLATION_BUDGET["offset_targets"],
            release=ABLATION_BUDGET["release_targets"],
        ),
        seeds=ABLATION_CONFIG["target_seeds"],
        starts=ABLATION_CONFIG["starts_per_family"],
        arc_deg=POLICY_CONFIG["arc_deg"],
        jitter_m=POLICY_CONFIG["target_jitter_m"],
    script:
        "../workflow_scripts/ablation_targets.py"


rule ablation_offsets:
    """Each event rule's offset delta, fitted on the offset targets."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        offset=f"{ABLATION_DIR}/targets_offset.parquet",
        code=imports("ablation_offsets"),
    output:
        f"{ABLATION_DIR}/offsets.json",
    log:
        "logs/ablation/offsets.log",
    benchmark:
        "benchmarks/ablation/offsets.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        triggers=TRIGGERS,
        offset_range_s=ABLATION_CONFIG["offset_range_s"],
    script:
        "../workflow_scripts/ablation_offsets.py"


rule ablation_rules:
    """Target-only, clock and the three triggers, and the references, on the release targets."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        offsets=f"{ABLATION_DIR}/offsets.json",
        release=f"{ABLATION_DIR}/targets_release.parquet",
        code=imports("ablation_rules"),
    output:
        f"{ABLATION_DIR}/rules.parquet",
    log:
        "logs/ablation/rules.log",
    benchmark:
        "benchmarks/ablation/rules.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        triggers=TRIGGERS,
        clock_s=ABLATION_CONFIG["clock_s"],
    script:
        "../workflow_scripts/ablation_rules.py"


rule ablation_bend:
    """Bend-point propagation in the selected policy's successes and in the recorded strikes."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        shards=expand(RESAMPLED_SHARD, shard=ROLE_SHARDS["train"]),
        metas=metas_of(**HOLD),
        code=imports("ablation_bend"),
    output:
        bend=f"{ABLATION_DIR}/bend.json",
        outcomes=f"{ABLATION_DIR}/selected_evaluation.parquet",
    log:
        "logs/ablation/bend.log",
    benchmark:
        "benchmarks/ablation/bend.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        groups=HOLD_GROUPS,
    script:
        "../workflow_scripts/ablation_bend.py"


rule ablation_perturb:
    """Median miss and mean peak speed under pre-release perturbations of the hold's error scale."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        hold=f"{DYNAMICS_DIR}/hold.json",
        code=imports("ablation_perturb"),
    output:
        f"{ABLATION_DIR}/perturb.json",
    log:
        "logs/ablation/perturb.log",
    benchmark:
        "benchmarks/ablation/perturb.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        scales=ABLATION_CONFIG["perturbation_scales"],
        draws=ABLATION_BUDGET["perturbation_draws"],
        seed=config["seed"],
    script:
        "../workflow_scripts/ablation_perturb.py"


rule ablation_summary:
    """Fig. 6 statistics: rule rewards (family bootstrap), attachment (Wilson, McNemar), projected
    fractions, tolerance sweep, bend point, perturbation."""
    input:
        offsets=f"{ABLATION_DIR}/offsets.json",
        rules=f"{ABLATION_DIR}/rules.parquet",
        learned=f"{ABLATION_DIR}/selected_evaluation.parquet",
        fixed=f"{POLICY_DIR}/eval/fixed.parquet",
        bend=f"{ABLATION_DIR}/bend.json",
        perturb=f"{ABLATION_DIR}/perturb.json",
        code=imports("ablation_summary"),
    output:
        f"{ABLATION_DIR}/summary.json",
    log:
        "logs/ablation/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        reward=POLICY_CONFIG["reward"],
        tolerances=POLICY_CONFIG["tolerances_m"],
        seed=config["seed"],
        n_boot=ABLATION_CONFIG["bootstrap_resamples"],
    script:
        "../workflow_scripts/ablation_summary.py"


rule fig_ablation:
    """Fig. 6: timing reward and attachment per release rule, attachment over tolerance."""
    input:
        summary=f"{ABLATION_DIR}/summary.json",
        code=imports("fig_ablation"),
    output:
        pdf="results/figs/fig6_ablation.pdf",
        png=report(
            "results/figs/fig6_ablation.png",
            caption=caption("fig6_ablation"),
            category=category("fig6_ablation"),
        ),
    log:
        "logs/fig_ablation.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/fig_ablation.py"


rule table_ablation_claims:
    """Every number of the ablation paragraphs beside the paper's value."""
    input:
        summary=f"{ABLATION_DIR}/summary.json",
        reference="reference/paper_values.yaml",
        code=imports("ablation_claims"),
    output:
        f"{ABLATION_DIR}/claims.csv",
    log:
        "logs/ablation/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/ablation_claims.py"

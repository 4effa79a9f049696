# Release-rule ablation, bend point and pre-release perturbation (paper IV-B, V-A, V-B, Fig. 6,
# Table I "Release targets"; docs/ablation.md). Offsets are fitted on the offset targets only; the
# release-evaluation targets are read only by ablation_rules (esnap check-separation).

ABL = "results/ablation"
ACFG = config["ablation"]
ABUDGET = BUDGET["ablation"]
# The trigger thresholds; the grid step, anchor and timing set are the simulator's (the protocol's).
TRIGGERS = dict(
    s1_rate_deg_s=ACFG["s1_rate_deg_s"], tip_speed_mps=ACFG["tip_speed_mps"]
)


rule ablation_targets:
    """Offset and release-evaluation targets in target families, each set from its own seed."""
    input:
        workspace=f"{POL}/workspace.json",
        code=imports("ablation_targets"),
    output:
        offset=f"{ABL}/targets_offset.parquet",
        release=f"{ABL}/targets_release.parquet",
    log:
        "logs/ablation/targets.log",
    conda:
        "../envs/esnap.yaml"
    params:
        sizes=dict(offset=ABUDGET["offset_targets"], release=ABUDGET["release_targets"]),
        seeds=ACFG["target_seeds"],
        starts=ACFG["starts_per_family"],
        arc_deg=PCFG["arc_deg"],
        jitter_m=PCFG["target_jitter_m"],
    script:
        "../workflow_scripts/ablation_targets.py"


rule ablation_offsets:
    """Each event rule's offset delta, fitted on the offset targets."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        offset=f"{ABL}/targets_offset.parquet",
        code=imports("ablation_offsets"),
    output:
        f"{ABL}/offsets.json",
    log:
        "logs/ablation/offsets.log",
    benchmark:
        "benchmarks/ablation/offsets.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
        triggers=TRIGGERS,
        offset_range_s=ACFG["offset_range_s"],
    script:
        "../workflow_scripts/ablation_offsets.py"


rule ablation_rules:
    """Target-only, clock and the three triggers, and the references, on the release targets."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        offsets=f"{ABL}/offsets.json",
        release=f"{ABL}/targets_release.parquet",
        code=imports("ablation_rules"),
    output:
        f"{ABL}/rules.parquet",
    log:
        "logs/ablation/rules.log",
    benchmark:
        "benchmarks/ablation/rules.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
        triggers=TRIGGERS,
        clock_s=ACFG["clock_s"],
    script:
        "../workflow_scripts/ablation_rules.py"


rule ablation_bend:
    """Bend-point propagation in the selected policy's successes and in the recorded strikes."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        evaluation=f"{POL}/targets_evaluation.parquet",
        shards=expand("results/data/50hz/{shard}.parquet", shard=ROLE_SHARDS["train"]),
        metas=metas_of(**HOLD),
        code=imports("ablation_bend"),
    output:
        bend=f"{ABL}/bend.json",
        outcomes=f"{ABL}/selected_evaluation.parquet",
    log:
        "logs/ablation/bend.log",
    benchmark:
        "benchmarks/ablation/bend.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
        groups=HOLD_GROUPS,
    script:
        "../workflow_scripts/ablation_bend.py"


rule ablation_perturb:
    """Median miss and mean peak speed under pre-release perturbations of the hold's error scale."""
    input:
        **SIMULATOR,
        runs=SHARED_RUNS,
        evaluation=f"{POL}/targets_evaluation.parquet",
        hold=f"{DYN}/hold.json",
        code=imports("ablation_perturb"),
    output:
        f"{ABL}/perturb.json",
    log:
        "logs/ablation/perturb.log",
    benchmark:
        "benchmarks/ablation/perturb.tsv"
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
        scales=ACFG["perturbation_scales"],
        draws=ABUDGET["perturbation_draws"],
        seed=config["seed"],
    script:
        "../workflow_scripts/ablation_perturb.py"


rule ablation_summary:
    """Fig. 6 statistics: rule rewards (family bootstrap), attachment (Wilson, McNemar), projected
    fractions, tolerance sweep, bend point, perturbation."""
    input:
        offsets=f"{ABL}/offsets.json",
        rules=f"{ABL}/rules.parquet",
        learned=f"{ABL}/selected_evaluation.parquet",
        fixed=f"{POL}/eval/fixed.parquet",
        bend=f"{ABL}/bend.json",
        perturb=f"{ABL}/perturb.json",
        code=imports("ablation_summary"),
    output:
        f"{ABL}/summary.json",
    log:
        "logs/ablation/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        reward=PCFG["reward"],
        tolerances=PCFG["tolerances_m"],
        seed=config["seed"],
        n_boot=ACFG["bootstrap_resamples"],
    script:
        "../workflow_scripts/ablation_summary.py"


rule fig_ablation:
    """Fig. 6: timing reward and attachment per release rule, attachment over tolerance."""
    input:
        summary=f"{ABL}/summary.json",
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
        summary=f"{ABL}/summary.json",
        reference="reference/paper_values.yaml",
        code=imports("ablation_claims"),
    output:
        f"{ABL}/claims.csv",
    log:
        "logs/ablation/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/ablation_claims.py"

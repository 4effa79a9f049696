# Policy search (paper IV-B, IV-C, V-A, V-B; docs/design.md section 4, step 6): the workspace and target
# sets, one CMA-ES job per architecture x seed, the selected policies on the 400 evaluation
# targets, the best fixed primitive, the analyses, Fig. 5 and results/policy/claims.csv.
# Evaluation targets are read only by policy_evaluate and policy_fixed (esnap check-separation).

# POLICY_DIR, POLICY_CONFIG, POLICY_BUDGET, the runs (POLICY_RUNS_OF, POLICY_RUNS, POLICY_EVALUATIONS,
# SHARED_RUNS) and the simulator (SIMULATOR, SIMULATOR_PARAMS), which later stages read too, are
# rules/common.smk's.


wildcard_constraints:
    arch="|".join(POLICY_BUDGET["seeds"]),


rule policy_workspace:
    """Strike cloud, strike-bearing offset and directional workspace of the training groups."""
    input:
        shards=expand(RESAMPLED_SHARD, shard=ROLE_SHARDS["train"]),
        metas=metas_of(**HOLD),
        bank=f"{DYNAMICS_DIR}/hold_bank.npz",
        code=imports("policy_workspace"),
    output:
        f"{POLICY_DIR}/workspace.json",
    log:
        "logs/policy/workspace.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        groups=HOLD_GROUPS,
        after_s1=DYNAMICS_CONFIG["after_s1_s"],
        ee_m=config["rig"]["end_effector_m"],
        protocol=protocol_params("primitive"),
    script:
        "../workflow_scripts/policy_workspace.py"


rule policy_targets:
    """Training (per generation), selection and evaluation targets, each set from its own seed."""
    input:
        workspace=f"{POLICY_DIR}/workspace.json",
        code=imports("policy_targets"),
    output:
        training=f"{POLICY_DIR}/targets_training.parquet",
        selection=f"{POLICY_DIR}/targets_selection.parquet",
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
    log:
        "logs/policy/targets.log",
    conda:
        "../envs/esnap.yaml"
    params:
        sizes=TARGET_SIZES,
        per_generation=POLICY_BUDGET["targets_per_candidate"],
        seeds=POLICY_CONFIG["target_seeds"],
        arc_deg=POLICY_CONFIG["arc_deg"],
        jitter_m=POLICY_CONFIG["target_jitter_m"],
    script:
        "../workflow_scripts/policy_targets.py"


rule policy_search:
    """CMA-ES for one architecture and seed; held-out reward on the selection targets per generation."""
    input:
        **SIMULATOR,
        training=f"{POLICY_DIR}/targets_training.parquet",
        selection=f"{POLICY_DIR}/targets_selection.parquet",
        code=imports("policy_search"),
    output:
        run=f"{POLICY_DIR}/runs/{{arch}}_seed{{seed}}.json",
        state=f"{POLICY_DIR}/runs/{{arch}}_seed{{seed}}.cma.pkl",
    log:
        "logs/policy/search_{arch}_seed{seed}.log",
    benchmark:
        "benchmarks/policy/search_{arch}_seed{seed}.tsv"
    # The ablation and the deployment need only the shared runs: those go first, and the jobs that
    # read them go before the other searches; the other searches go before the short jobs
    # (search_priority, rules/common.smk).
    priority: search_priority
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        runs=lambda wc: [(wc.arch, int(wc.seed))],
        generations=POLICY_BUDGET["generations"],
        popsize=POLICY_BUDGET["popsize"],
        start=POLICY_CONFIG["start"],
        # where a smaller budget would have stopped: its selection is kept (rules/robustness.smk)
        snapshots=[
            round(f * POLICY_BUDGET["generations"])
            for f in POLICY_CONFIG["robustness"]["budget_factors"].values()
            if f < 1
        ],
    script:
        "../workflow_scripts/policy_search.py"


# With config policy.batch_runs the benchmark's runs are one job instead: every run's generation
# in one batch of rollouts, the schedule for a GPU (docs/cluster.md, "One GPU"). Each run draws
# from its own generator, so it is the run policy_search makes, up to the batch's rounding.
if POLICY_CONFIG["batch_runs"]:

    ruleorder: policy_search_lockstep > policy_search

    use rule policy_search as policy_search_lockstep with:
        output:
            run=POLICY_RUNS,
            state=[r.removesuffix(".json") + ".cma.pkl" for r in POLICY_RUNS],
        log:
            "logs/policy/search_lockstep.log",
        benchmark:
            "benchmarks/policy/search_lockstep.tsv"
        priority: FIRST
        threads: workflow.cores
        params:
            runs=POLICY_RUNS_OF,


rule policy_evaluate:
    """The selected policy of one run on the evaluation targets."""
    input:
        **SIMULATOR,
        run=f"{POLICY_DIR}/runs/{{arch}}_seed{{seed}}.json",
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        code=imports("policy_evaluate"),
    output:
        f"{POLICY_DIR}/eval/{{arch}}_seed{{seed}}.parquet",
    log:
        "logs/policy/evaluate_{arch}_seed{seed}.log",
    priority: shared_run
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
    script:
        "../workflow_scripts/policy_evaluate.py"


rule policy_fixed:
    """The best of the fixed primitives on the selection targets, evaluated on the evaluation targets."""
    input:
        **SIMULATOR,
        selection=f"{POLICY_DIR}/targets_selection.parquet",
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        code=imports("policy_fixed"),
    output:
        eval=f"{POLICY_DIR}/eval/fixed.parquet",
        summary=f"{POLICY_DIR}/fixed.json",
    log:
        "logs/policy/fixed.log",
    benchmark:
        "benchmarks/policy/fixed.tsv"
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        seed=config["seed"],
    script:
        "../workflow_scripts/policy_fixed.py"


rule policy_summary:
    """V-A and V-B statistics: reward per architecture and Mann-Whitney tests over seeds, attachment
    (Eq. 11) over the tolerance sweep, evaluations to reach the matched centralised level, and the
    selected shared policy against the best fixed primitive on the evaluation targets.
    """
    input:
        runs=POLICY_RUNS,
        evals=POLICY_EVALUATIONS,
        fixed=f"{POLICY_DIR}/eval/fixed.parquet",
        code=imports("policy_summary"),
    output:
        f"{POLICY_DIR}/summary.json",
    log:
        "logs/policy/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        tolerances=POLICY_CONFIG["tolerances_m"],
        d_f=POLICY_CONFIG["reward"]["d_f_m"],
        v_min=POLICY_CONFIG["reward"]["v_min_sim_mps"],
        budget_evaluations=evaluations(
            POLICY_BUDGET["generations"],
            POLICY_BUDGET["popsize"],
            POLICY_BUDGET["targets_per_candidate"],
        ),
        protocol=protocol_params("primitive"),
    script:
        "../workflow_scripts/policy_summary.py"


rule fig_benchmark:
    """Fig. 5: held-out reward over evaluations, attachment over tolerance, evaluations to reach."""
    input:
        summary=f"{POLICY_DIR}/summary.json",
        code=imports("fig_benchmark"),
    output:
        pdf="results/figs/fig5_benchmark.pdf",
        png=report(
            "results/figs/fig5_benchmark.png",
            caption=caption("fig5_benchmark"),
            category=category("fig5_benchmark"),
        ),
    log:
        "logs/fig_benchmark.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/fig_benchmark.py"


rule table_policy_claims:
    """Every architecture and generalisation number of sections V-A and V-B beside the paper's value."""
    input:
        summary=f"{POLICY_DIR}/summary.json",
        reference="reference/paper_values.yaml",
        code=imports("policy_claims"),
    output:
        f"{POLICY_DIR}/claims.csv",
    log:
        "logs/policy/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/policy_claims.py"

# Policy search (paper IV-B, IV-C, V-A, V-B; docs/design.md section 4, step 6): the workspace and target
# sets, one CMA-ES job per architecture x seed, the selected policies on the 400 evaluation
# targets, the best fixed primitive, the analyses, Fig. 5 and results/policy/claims.csv.
# Evaluation targets are read only by policy_evaluate and policy_fixed (esnap check-separation).

# POL, PCFG, PBUDGET, the runs (POLICY_RUNS_OF, POLICY_RUNS, POLICY_EVALS, SHARED_RUNS) and the
# simulator (SIMULATOR, SIM_PARAMS), which later stages read too, are rules/common.smk's.


wildcard_constraints:
    arch="|".join(PBUDGET["seeds"]),


rule policy_workspace:
    """Strike cloud, strike-bearing offset and directional workspace of the training groups."""
    input:
        shards=expand("results/data/50hz/{shard}.parquet", shard=ROLE_SHARDS["train"]),
        metas=metas_of(**HOLD),
        bank=f"{DYN}/hold_bank.npz",
        code=imports("policy_workspace"),
    output:
        f"{POL}/workspace.json",
    log:
        "logs/policy/workspace.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        groups=HOLD_GROUPS,
        after_s1=DCFG["after_s1_s"],
        ee_m=config["rig"]["end_effector_m"],
        protocol=protocol_params("primitive"),
    script:
        "../workflow_scripts/policy_workspace.py"


rule policy_targets:
    """Training (per generation), selection and evaluation targets, each set from its own seed."""
    input:
        workspace=f"{POL}/workspace.json",
        code=imports("policy_targets"),
    output:
        training=f"{POL}/targets_training.parquet",
        selection=f"{POL}/targets_selection.parquet",
        evaluation=f"{POL}/targets_evaluation.parquet",
    log:
        "logs/policy/targets.log",
    conda:
        "../envs/esnap.yaml"
    params:
        sizes=TARGET_SIZES,
        per_generation=PBUDGET["targets_per_candidate"],
        seeds=PCFG["target_seeds"],
        arc_deg=PCFG["arc_deg"],
        jitter_m=PCFG["target_jitter_m"],
    script:
        "../workflow_scripts/policy_targets.py"


rule policy_search:
    """CMA-ES for one architecture and seed; held-out reward on the selection targets per generation."""
    input:
        **SIMULATOR,
        training=f"{POL}/targets_training.parquet",
        selection=f"{POL}/targets_selection.parquet",
        code=imports("policy_search"),
    output:
        run=f"{POL}/runs/{{arch}}_seed{{seed}}.json",
        state=f"{POL}/runs/{{arch}}_seed{{seed}}.cma.pkl",
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
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
        runs=lambda wc: [(wc.arch, int(wc.seed))],
        generations=PBUDGET["generations"],
        popsize=PBUDGET["popsize"],
        start=PCFG["start"],
        # where a smaller budget would have stopped: its selection is kept (rules/robustness.smk)
        snapshots=[
            round(f * PBUDGET["generations"])
            for f in PCFG["robustness"]["budget_factors"].values()
            if f < 1
        ],
    script:
        "../workflow_scripts/policy_search.py"


# With config policy.batch_runs the benchmark's runs are one job instead: every run's generation
# in one batch of rollouts, the schedule for a GPU (docs/cluster.md, "One GPU"). Each run draws
# from its own generator, so it is the run policy_search makes, up to the batch's rounding.
if PCFG["batch_runs"]:

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
        run=f"{POL}/runs/{{arch}}_seed{{seed}}.json",
        evaluation=f"{POL}/targets_evaluation.parquet",
        code=imports("policy_evaluate"),
    output:
        f"{POL}/eval/{{arch}}_seed{{seed}}.parquet",
    log:
        "logs/policy/evaluate_{arch}_seed{seed}.log",
    priority: shared_run
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
    script:
        "../workflow_scripts/policy_evaluate.py"


rule policy_fixed:
    """The best of the fixed primitives on the selection targets, evaluated on the evaluation targets."""
    input:
        **SIMULATOR,
        selection=f"{POL}/targets_selection.parquet",
        evaluation=f"{POL}/targets_evaluation.parquet",
        code=imports("policy_fixed"),
    output:
        eval=f"{POL}/eval/fixed.parquet",
        summary=f"{POL}/fixed.json",
    log:
        "logs/policy/fixed.log",
    benchmark:
        "benchmarks/policy/fixed.tsv"
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIM_RESOURCES,
    params:
        **SIM_PARAMS,
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
        evals=POLICY_EVALS,
        fixed=f"{POL}/eval/fixed.parquet",
        code=imports("policy_summary"),
    output:
        f"{POL}/summary.json",
    log:
        "logs/policy/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        tolerances=PCFG["tolerances_m"],
        d_f=PCFG["reward"]["d_f_m"],
        v_min=PCFG["reward"]["v_min_sim_mps"],
        budget_evaluations=evaluations(
            PBUDGET["generations"],
            PBUDGET["popsize"],
            PBUDGET["targets_per_candidate"],
        ),
        protocol=protocol_params("primitive"),
    script:
        "../workflow_scripts/policy_summary.py"


rule fig_benchmark:
    """Fig. 5: held-out reward over evaluations, attachment over tolerance, evaluations to reach."""
    input:
        summary=f"{POL}/summary.json",
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
        summary=f"{POL}/summary.json",
        reference="reference/paper_values.yaml",
        code=imports("policy_claims"),
    output:
        f"{POL}/claims.csv",
    log:
        "logs/policy/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/policy_claims.py"

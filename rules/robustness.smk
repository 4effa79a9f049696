# Is the architecture ranking robust (docs/policy.md, "Robustness")? The benchmark of rules/policy.smk,
# unchanged, against three variants: targets drawn uniformly over the measured workspace instead of
# around recorded strikes, and smaller and larger evaluation budgets. A smaller budget is the policy
# each run had selected at that point (CMA-ES does not depend on the total budget, so a run stopped
# there selects exactly that); a larger one continues each run from its CMA-ES state on further
# training targets. Results: results/robustness/{summary.json,claims.csv}, Fig. S1.

ROBUSTNESS_DIR = "results/robustness"
ROBUSTNESS_CONFIG = POLICY_CONFIG["robustness"]
GENERATIONS = POLICY_BUDGET["generations"]
BUDGET_GENERATIONS = {
    v: round(f * GENERATIONS) for v, f in ROBUSTNESS_CONFIG["budget_factors"].items()
}
SHORTER = [v for v, g in BUDGET_GENERATIONS.items() if g < GENERATIONS]
LONGER = [v for v, g in BUDGET_GENERATIONS.items() if g > GENERATIONS]
ROBUSTNESS_VARIANTS = ["uniform", *BUDGET_GENERATIONS]
UNIFORM_TARGETS = {
    n: f"{ROBUSTNESS_DIR}/uniform/targets_{n}.parquet"
    for n in ("training", "selection", "evaluation")
}


wildcard_constraints:
    variant="|".join(ROBUSTNESS_VARIANTS),
    longer="|".join(LONGER) or "-",


rule robustness_targets:
    """Uniform workspace targets (training per generation, selection, evaluation; a seed each) and the
    training targets of the generations the continued runs add (up to the largest budget).
    """
    input:
        workspace=f"{POLICY_DIR}/workspace.json",
        code=imports("robustness_targets"),
    output:
        **{f"uniform_{n}": f for n, f in UNIFORM_TARGETS.items()},
        extension=f"{ROBUSTNESS_DIR}/targets_extension.parquet",
    log:
        "logs/robustness/targets.log",
    conda:
        "../envs/esnap.yaml"
    params:
        uniform_sizes=TARGET_SIZES,
        extension=(
            GENERATIONS,
            max([BUDGET_GENERATIONS[v] for v in LONGER], default=GENERATIONS),
        ),
        per_generation=POLICY_BUDGET["targets_per_candidate"],
        seeds=ROBUSTNESS_CONFIG["target_seeds"],
        arc_deg=POLICY_CONFIG["arc_deg"],
        jitter_m=POLICY_CONFIG["target_jitter_m"],
    script:
        "../workflow_scripts/robustness_targets.py"


use rule policy_search as robustness_search_uniform with:
    input:
        **SIMULATOR,
        training=UNIFORM_TARGETS["training"],
        selection=UNIFORM_TARGETS["selection"],
        code=imports("policy_search"),
    output:
        run=f"{ROBUSTNESS_DIR}/uniform/runs/{{arch}}_seed{{seed}}.json",
        state=f"{ROBUSTNESS_DIR}/uniform/runs/{{arch}}_seed{{seed}}.cma.pkl",
    log:
        "logs/robustness/search_uniform_{arch}_seed{seed}.log",
    benchmark:
        "benchmarks/robustness/search_uniform_{arch}_seed{seed}.tsv"
    priority: 0
    params:
        snapshots=[],


use rule policy_search as robustness_search_longer with:
    input:
        **SIMULATOR,
        resume=f"{POLICY_DIR}/runs/{{arch}}_seed{{seed}}.json",
        resume_state=f"{POLICY_DIR}/runs/{{arch}}_seed{{seed}}.cma.pkl",
        training=f"{ROBUSTNESS_DIR}/targets_extension.parquet",
        selection=f"{POLICY_DIR}/targets_selection.parquet",
        code=imports("policy_search"),
    output:
        run=f"{ROBUSTNESS_DIR}/{{longer}}/runs/{{arch}}_seed{{seed}}.json",
        state=f"{ROBUSTNESS_DIR}/{{longer}}/runs/{{arch}}_seed{{seed}}.cma.pkl",
    log:
        "logs/robustness/search_{longer}_{arch}_seed{seed}.log",
    benchmark:
        "benchmarks/robustness/search_{longer}_{arch}_seed{seed}.tsv"
    priority: 0
    params:
        generations=lambda wc: BUDGET_GENERATIONS[wc.longer],
        snapshots=[],


rule robustness_fixed:
    """The best fixed primitive, selected and evaluated on the uniform targets."""
    input:
        **SIMULATOR,
        selection=UNIFORM_TARGETS["selection"],
        evaluation=UNIFORM_TARGETS["evaluation"],
        code=imports("policy_fixed"),
    output:
        eval=f"{ROBUSTNESS_DIR}/uniform/eval/fixed.parquet",
        summary=f"{ROBUSTNESS_DIR}/uniform/fixed.json",
    log:
        "logs/robustness/fixed.log",
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


rule robustness_evaluate:
    """A variant's selected policy of one run on that variant's evaluation targets."""
    input:
        **SIMULATOR,
        # a smaller budget's run is the benchmark's, stopped there
        run=lambda wc: (
            f"{POLICY_DIR}/runs/{wc.arch}_seed{wc.seed}.json"
            if wc.variant in SHORTER
            else f"{ROBUSTNESS_DIR}/{wc.variant}/runs/{wc.arch}_seed{wc.seed}.json"
        ),
        evaluation=lambda wc: (
            UNIFORM_TARGETS["evaluation"]
            if wc.variant == "uniform"
            else f"{POLICY_DIR}/targets_evaluation.parquet"
        ),
        code=imports("policy_evaluate"),
    output:
        f"{ROBUSTNESS_DIR}/{{variant}}/eval/{{arch}}_seed{{seed}}.parquet",
    log:
        "logs/robustness/evaluate_{variant}_{arch}_seed{seed}.log",
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        generations=lambda wc: (
            BUDGET_GENERATIONS[wc.variant] if wc.variant in SHORTER else None
        ),
    script:
        "../workflow_scripts/policy_evaluate.py"


rule robustness_summary:
    """Each variant summarised as the benchmark is (reward, Mann-Whitney tests, attachment), with the
    ranking of the four architectures and whether it is the benchmark's."""
    input:
        benchmark_runs=POLICY_RUNS,
        benchmark_evals=POLICY_EVALUATIONS,
        benchmark_fixed=f"{POLICY_DIR}/eval/fixed.parquet",
        uniform_runs=[
            f"{ROBUSTNESS_DIR}/uniform/runs/{a}_seed{s}.json"
            for a, s in POLICY_RUNS_OF
        ],
        uniform_fixed=f"{ROBUSTNESS_DIR}/uniform/eval/fixed.parquet",
        longer_runs=[
            f"{ROBUSTNESS_DIR}/{v}/runs/{a}_seed{s}.json"
            for v in LONGER
            for a, s in POLICY_RUNS_OF
        ],
        evals=[
            f"{ROBUSTNESS_DIR}/{v}/eval/{a}_seed{s}.parquet"
            for v in ROBUSTNESS_VARIANTS
            for a, s in POLICY_RUNS_OF
        ],
        code=imports("robustness_summary"),
    output:
        f"{ROBUSTNESS_DIR}/summary.json",
    log:
        "logs/robustness/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        variants=ROBUSTNESS_VARIANTS,
        budget_generations=BUDGET_GENERATIONS,
        generations=GENERATIONS,
        tolerances=POLICY_CONFIG["tolerances_m"],
        d_f=POLICY_CONFIG["reward"]["d_f_m"],
        v_min=POLICY_CONFIG["reward"]["v_min_sim_mps"],
        evaluations_per_generation=evaluations(
            1, POLICY_BUDGET["popsize"], POLICY_BUDGET["targets_per_candidate"]
        ),
        protocol=protocol_params("primitive"),
    script:
        "../workflow_scripts/robustness_summary.py"


rule fig_robustness:
    """Fig. S1: final held-out reward and attachment at 5 cm per architecture, benchmark and variants."""
    input:
        summary=f"{ROBUSTNESS_DIR}/summary.json",
        code=imports("fig_robustness"),
    output:
        pdf="results/figs/figS1_robustness.pdf",
        png=report(
            "results/figs/figS1_robustness.png",
            caption="../report/figS1_robustness.rst",
            category="Policy",
        ),
    log:
        "logs/fig_robustness.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/fig_robustness.py"


rule table_robustness_claims:
    """The architecture result on each variant beside the paper's benchmark values."""
    input:
        summary=f"{ROBUSTNESS_DIR}/summary.json",
        reference="reference/paper_values.yaml",
        code=imports("robustness_claims"),
    output:
        f"{ROBUSTNESS_DIR}/variants.csv",
    log:
        "logs/robustness/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/robustness_claims.py"

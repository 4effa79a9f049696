# Does the architecture ranking depend on where the search starts (docs/policy.md, "Starting point")?
# The benchmark's searches of rules/policy.smk again, unchanged but for their start (config
# policy.sensitivity: zero weights at larger steps, Glorot-uniform weights), for the architectures each
# start names; the benchmark's own start (policy.start) is its runs. Each start is read by the rule
# docs/policy.md fixed before the first run. Results: results/sensitivity/{summary.json,starts.csv},
# Fig. S2. Then what the landscape allows: CMA-ES on each of the first evaluation targets' six commands
# directly, the policies' rewards against that optimum, the optimum regressed on the target features
# per section, and each architecture fitted to it by least squares (results/landscape/).

SENSITIVITY_DIR = "results/sensitivity"
SENSITIVITY_CONFIG = POLICY_CONFIG["sensitivity"]
BENCHMARK_START = (
    f"{POLICY_CONFIG['start']['init']}-{POLICY_CONFIG['start']['sigma0']:g}"
)
SENSITIVITY_RUNS_OF = [
    (start, arch, seed)
    for start, s in SENSITIVITY_CONFIG.items()
    for arch in s["archs"]
    for seed in range(POLICY_BUDGET["seeds"][arch])
]
LANDSCAPE_DIR = "results/landscape"
LANDSCAPE_BUDGET = BUDGET["landscape"]


wildcard_constraints:
    start="|".join(s.replace(".", r"\.") for s in SENSITIVITY_CONFIG),


use rule policy_search as sensitivity_search with:
    input:
        **SIMULATOR,
        training=f"{POLICY_DIR}/targets_training.parquet",
        selection=f"{POLICY_DIR}/targets_selection.parquet",
        code=imports("policy_search"),
    output:
        run=f"{SENSITIVITY_DIR}/{{start}}/runs/{{arch}}_seed{{seed}}.json",
        state=f"{SENSITIVITY_DIR}/{{start}}/runs/{{arch}}_seed{{seed}}.cma.pkl",
    log:
        "logs/sensitivity/search_{start}_{arch}_seed{seed}.log",
    benchmark:
        "benchmarks/sensitivity/search_{start}_{arch}_seed{seed}.tsv"
    priority: 0
    params:
        start=lambda wc: {
            k: v for k, v in SENSITIVITY_CONFIG[wc.start].items() if k != "archs"
        },
        snapshots=[],


use rule policy_evaluate as sensitivity_evaluate with:
    input:
        **SIMULATOR,
        run=f"{SENSITIVITY_DIR}/{{start}}/runs/{{arch}}_seed{{seed}}.json",
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        code=imports("policy_evaluate"),
    output:
        f"{SENSITIVITY_DIR}/{{start}}/eval/{{arch}}_seed{{seed}}.parquet",
    log:
        "logs/sensitivity/evaluate_{start}_{arch}_seed{seed}.log",
    priority: 0


rule sensitivity_summary:
    """Each start summarised as the benchmark is, read by the fixed rule, with the slope probe of every
    selected policy and of the first candidates of every start."""
    input:
        benchmark_runs=POLICY_RUNS,
        benchmark_evals=POLICY_EVALUATIONS,
        fixed=f"{POLICY_DIR}/eval/fixed.parquet",
        runs=[
            f"{SENSITIVITY_DIR}/{s}/runs/{a}_seed{i}.json"
            for s, a, i in SENSITIVITY_RUNS_OF
        ],
        evals=[
            f"{SENSITIVITY_DIR}/{s}/eval/{a}_seed{i}.parquet"
            for s, a, i in SENSITIVITY_RUNS_OF
        ],
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        workspace=f"{POLICY_DIR}/workspace.json",
        code=imports("sensitivity_summary"),
    output:
        f"{SENSITIVITY_DIR}/summary.json",
    log:
        "logs/sensitivity/summary.log",
    conda:
        "../envs/esnap.yaml"
    params:
        starts={BENCHMARK_START: POLICY_CONFIG["start"], **SENSITIVITY_CONFIG},
        tolerances=POLICY_CONFIG["tolerances_m"],
        d_f=POLICY_CONFIG["reward"]["d_f_m"],
        v_min=POLICY_CONFIG["reward"]["v_min_sim_mps"],
        budget_evaluations=evaluations(
            POLICY_BUDGET["generations"],
            POLICY_BUDGET["popsize"],
            POLICY_BUDGET["targets_per_candidate"],
        ),
        protocol=protocol_params("primitive"),
        seed=config["seed"],
    script:
        "../workflow_scripts/sensitivity_summary.py"


rule fig_sensitivity:
    """Fig. S2: final held-out reward per architecture and start, and how tied the shared sections are."""
    input:
        summary=f"{SENSITIVITY_DIR}/summary.json",
        code=imports("fig_sensitivity"),
    output:
        pdf="results/figs/figS2_sensitivity.pdf",
        png=report(
            "results/figs/figS2_sensitivity.png",
            # a static caption: the ledger writes captions only for the paper's figures
            caption="../report/figS2_sensitivity.rst",
            category=category("figS2_sensitivity"),
        ),
    log:
        "logs/fig_sensitivity.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/fig_sensitivity.py"


rule table_sensitivity:
    """Per start: rewards, the reading, the budget share to the centralised level, the slope probe."""
    input:
        summary=f"{SENSITIVITY_DIR}/summary.json",
        code=imports("sensitivity_table"),
    output:
        csv=f"{SENSITIVITY_DIR}/starts.csv",
        html=report(
            f"{SENSITIVITY_DIR}/starts.html",
            caption="../report/sensitivity_starts.rst",
            category="Starting point",
        ),
    log:
        "logs/sensitivity/table.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/sensitivity_table.py"


rule landscape_optimum:
    """Per target, the best six commands CMA-ES finds on them directly (the policies' simulator,
    reward and bounds), restarted from random points, in two repeats with their own seeds.
    """
    input:
        **SIMULATOR,
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        code=imports("landscape_optimum"),
    output:
        f"{LANDSCAPE_DIR}/optimum.parquet",
    log:
        "logs/landscape/optimum.log",
    benchmark:
        "benchmarks/landscape/optimum.tsv"
    conda:
        "../envs/esnap.yaml"
    threads: 2
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        size=LANDSCAPE_BUDGET,
        method=POLICY_CONFIG["landscape"],
    script:
        "../workflow_scripts/landscape_optimum.py"


rule landscape_summary:
    """What any policy could still gain, whether the sections need distinct slopes, and each
    architecture's capacity apart from search (least squares on the optimum, scored by the reward).
    """
    input:
        **SIMULATOR,
        optimum=f"{LANDSCAPE_DIR}/optimum.parquet",
        evaluation=f"{POLICY_DIR}/targets_evaluation.parquet",
        benchmark_evals=POLICY_EVALUATIONS,
        fixed=f"{POLICY_DIR}/eval/fixed.parquet",
        code=imports("landscape_summary"),
    output:
        summary=f"{LANDSCAPE_DIR}/summary.json",
        table=f"{LANDSCAPE_DIR}/architectures.csv",
        html=report(
            f"{LANDSCAPE_DIR}/architectures.html",
            caption="../report/landscape_architectures.rst",
            category="Landscape",
        ),
    log:
        "logs/landscape/summary.log",
    benchmark:
        "benchmarks/landscape/summary.tsv"
    conda:
        "../envs/esnap.yaml"
    threads: 1
    resources:
        **SIMULATOR_RESOURCES,
    params:
        **SIMULATOR_PARAMS,
        seed=config["seed"],
    script:
        "../workflow_scripts/landscape_summary.py"

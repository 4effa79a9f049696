# Dynamics model (paper IV-A; docs/design.md section 4, step 5): the GRU ensemble of Eq. 3-4, the
# persistence baseline, validation errors, one sealed evaluation, the delay-sweep gate, the hold
# model, Fig. 4 and results/dynamics/claims.csv. Training and model selection see the train and
# validation windows only; windows_sealed.npz reaches dynamics_sealed_eval alone, after selection.

# DYNAMICS_DIR, DYNAMICS_CONFIG, DYNAMICS_MODELS, HOLD and HOLD_GROUPS, which later stages read too,
# are rules/common.smk's.
DYNAMICS_SEEDS = DYNAMICS_CONFIG["seeds"]
DYNAMICS_VALIDATIONS = expand(
    f"{DYNAMICS_DIR}/validation/seed{{seed}}.json", seed=DYNAMICS_SEEDS
)
SWEEP = dict(evidence_set="delay_sweep")
SWEEP_SHARDS = sorted(PLAN[PLAN.evidence_set == "delay_sweep"].shard.unique())


wildcard_constraints:
    seed=r"\d+",


rule dynamics_train:
    """Eq. 3-4 for one seed: 25-step open-loop rollouts; early stopping and selection on validation."""
    input:
        train="results/splits/windows_train.npz",
        validation="results/splits/windows_validation.npz",
        code=imports("dynamics_train"),
    output:
        model=f"{DYNAMICS_DIR}/models/seed{{seed}}.pt",
        curve=f"{DYNAMICS_DIR}/models/seed{{seed}}_curve.csv",
    log:
        "logs/dynamics/train_seed{seed}.log",
    benchmark:
        "benchmarks/dynamics/train_seed{seed}.tsv"
    conda:
        "../envs/esnap.yaml"
    threads: DYNAMICS_CONFIG["threads"]
    resources:
        # one GPU from the cluster when the config trains on cuda (profiles/slurm: --gpus=1)
        gpu=int(DYNAMICS_CONFIG["device"] == "cuda"),
    params:
        seed=lambda wc: int(wc.seed),
        device=DYNAMICS_CONFIG["device"],
        epochs=BUDGET["dynamics"]["epochs"],
        windows_per_epoch=BUDGET["dynamics"]["windows_per_epoch"],
        lr=DYNAMICS_CONFIG["lr"],
        batch_size=DYNAMICS_CONFIG["batch_size"],
        patience=DYNAMICS_CONFIG["patience"],
        val_windows=DYNAMICS_CONFIG["val_windows"],
    script:
        "../workflow_scripts/dynamics_train.py"


# With config dynamics.seeds_in_one_job (the local default) the seeds train side by side in one job
# of up to workflow.cores threads: three one-core jobs on two cores leave one idle while the third
# trains alone. Each seed's model is the one its own job gives; a cluster keeps a job per seed
# (profiles/slurm).
if DYNAMICS_CONFIG["seeds_in_one_job"]:

    ruleorder: dynamics_train_seeds > dynamics_train

    use rule dynamics_train as dynamics_train_seeds with:
        output:
            model=expand(f"{DYNAMICS_DIR}/models/seed{{seed}}.pt", seed=DYNAMICS_SEEDS),
            curve=expand(
                f"{DYNAMICS_DIR}/models/seed{{seed}}_curve.csv", seed=DYNAMICS_SEEDS
            ),
        log:
            "logs/dynamics/train_seeds.log",
        benchmark:
            "benchmarks/dynamics/train_seeds.tsv"
        threads: min(len(DYNAMICS_SEEDS) * DYNAMICS_CONFIG["threads"], workflow.cores)
        params:
            seed=DYNAMICS_SEEDS,


rule dynamics_persistence:
    """Persistence baseline x_hat_{t+h} = x_t on the validation windows, h = 1..35."""
    input:
        validation="results/splits/windows_validation.npz",
        code=imports("dynamics_persistence"),
    output:
        f"{DYNAMICS_DIR}/validation/persistence.json",
    log:
        "logs/dynamics/persistence.log",
    conda:
        "../envs/esnap.yaml"
    params:
        protocol=protocol_params("sampling", "rig"),
    script:
        "../workflow_scripts/dynamics_persistence.py"


rule dynamics_validate:
    """Validation tip error over h = 1..35 of one selected seed; carried-state vs re-encoded gap."""
    input:
        model=f"{DYNAMICS_DIR}/models/seed{{seed}}.pt",
        validation="results/splits/windows_validation.npz",
        code=imports("dynamics_validate"),
    output:
        f"{DYNAMICS_DIR}/validation/seed{{seed}}.json",
    log:
        "logs/dynamics/validate_seed{seed}.log",
    conda:
        "../envs/esnap.yaml"
    threads: DYNAMICS_CONFIG["threads"]
    params:
        protocol=protocol_params("sampling", "rig"),
    script:
        "../workflow_scripts/dynamics_validate.py"


rule dynamics_sealed_eval:
    """The single sealed evaluation: every selected seed and persistence, once, on all sealed windows.
    Listed after the validation results so that it runs only after model selection."""
    input:
        models=DYNAMICS_MODELS,
        selected=DYNAMICS_VALIDATIONS,
        sealed="results/splits/windows_sealed.npz",
        code=imports("dynamics_sealed_eval"),
    output:
        f"{DYNAMICS_DIR}/sealed/eval.json",
    log:
        "logs/dynamics/sealed_eval.log",
    conda:
        "../envs/esnap.yaml"
    threads: DYNAMICS_CONFIG["threads"]
    params:
        seeds=DYNAMICS_SEEDS,
        protocol=protocol_params("sampling", "rig"),
    script:
        "../workflow_scripts/dynamics_sealed_eval.py"


rule dynamics_gate:
    """Measured vs predicted peak tip speed and travel over the excluded delay sweep, per seed,
    rolled out from each trial's hold through the S2 and S1 releases."""
    input:
        models=DYNAMICS_MODELS,
        shards=expand(RESAMPLED_SHARD, shard=SWEEP_SHARDS),
        metas=metas_of(**SWEEP),
        code=imports("dynamics_gate"),
    output:
        f"{DYNAMICS_DIR}/gate.json",
    log:
        "logs/dynamics/gate.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        seeds=DYNAMICS_SEEDS,
        after_s1=DYNAMICS_CONFIG["after_s1_s"],
        protocol=protocol_params("sampling", "windows"),
    script:
        "../workflow_scripts/dynamics_gate.py"


rule dynamics_hold:
    """Hold bank (pre-S2-release configurations) of the training-split dynamics groups, canonical
    bearing; leave-one-session-out hold errors."""
    input:
        shards=expand(RESAMPLED_SHARD, shard=ROLE_SHARDS["train"]),
        metas=metas_of(**HOLD),
        code=imports("dynamics_hold"),
    output:
        bank=f"{DYNAMICS_DIR}/hold_bank.npz",
        summary=f"{DYNAMICS_DIR}/hold.json",
    log:
        "logs/dynamics/hold.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        groups=HOLD_GROUPS,
        protocol=protocol_params("primitive", "windows", "rig"),
    script:
        "../workflow_scripts/dynamics_hold.py"


rule table_dynamics_claims:
    """Every number of section IV-A beside the paper's value."""
    input:
        persistence=f"{DYNAMICS_DIR}/validation/persistence.json",
        validation=DYNAMICS_VALIDATIONS,
        sealed=f"{DYNAMICS_DIR}/sealed/eval.json",
        gate=f"{DYNAMICS_DIR}/gate.json",
        hold=f"{DYNAMICS_DIR}/hold.json",
        reference="reference/paper_values.yaml",
        code=imports("dynamics_claims"),
    output:
        f"{DYNAMICS_DIR}/claims.csv",
    log:
        "logs/dynamics/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/dynamics_claims.py"


rule fig_gates:
    """Fig. 4: validation tip error over the horizon; peak speed and travel over the delay sweep."""
    input:
        persistence=f"{DYNAMICS_DIR}/validation/persistence.json",
        validation=DYNAMICS_VALIDATIONS,
        gate=f"{DYNAMICS_DIR}/gate.json",
        code=imports("fig_gates"),
    output:
        pdf="results/figs/fig4_gates.pdf",
        png=report(
            "results/figs/fig4_gates.png",
            caption=caption("fig4_gates"),
            category=category("fig4_gates"),
        ),
    log:
        "logs/fig_gates.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    params:
        protocol=protocol_params("sampling", "windows"),
    script:
        "../workflow_scripts/fig_gates.py"

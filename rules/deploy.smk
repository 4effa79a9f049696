# Deployment (paper VI, Table II, Fig. 7; docs/deployment.md): the manifest exported from the
# selected shared policy, the trials run through `esnap deploy` (with the simulated rig: over the
# virtual Dynamixel bus; with a real rig: recorded in the lab into DEPLOYMENT_RAW), Table II and
# Fig. 7.
# The deployment recordings feed only Table II and Fig. 7 (esnap check-separation).

# DEPLOYMENT_DIR, DEPLOYMENT_RAW, DEPLOYED and the manifest's inputs (MANIFEST_INPUTS,
# MANIFEST_FILES), which the lineage and the report read too, are rules/common.smk's.
DEPLOYMENT_CONFIG = config["deployment"]
DEPLOYMENT_BUDGET = BUDGET["deployment"]


rule deploy_manifest:
    """Everything `esnap deploy` reads: the selected shared policy, ranges, workspace, envelope,
    placements, calibration, code version and the sha256 of every input."""
    input:
        **MANIFEST_INPUTS,
        schema="schemas/deployment_manifest.schema.json",
        code=imports("deploy_manifest"),
    output:
        f"{DEPLOYMENT_DIR}/manifest.json",
    log:
        "logs/deployment/manifest.log",
    priority: FIRST  # reads the shared runs (rules/policy.smk)
    conda:
        "../envs/esnap.yaml"
    params:
        deployment=DEPLOYMENT_CONFIG,
        policy=POLICY_PARAMS,
        placements=DEPLOYMENT_BUDGET["placements"],
        protocol=protocol_params("primitive", "rig"),
    script:
        "../workflow_scripts/deploy_manifest.py"


if TWIN:

    rule twin_deployment:
        """The trials through the virtual Dynamixel bus on the simulated rig, side by side."""
        input:
            manifest=f"{DEPLOYMENT_DIR}/manifest.json",
            code=imports("twin_deployment"),
        output:
            index=f"{DEPLOYMENT_RAW}/index.csv",
            groups=directory(f"{DEPLOYMENT_RAW}/groups"),
            aborted=f"{DEPLOYMENT_RAW}/aborted.json",
        log:
            "logs/deployment/trials.log",
        benchmark:
            "benchmarks/deployment/trials.tsv"
        # It deploys the shared runs, so it goes before the other searches and runs beside them:
        # real-time trials use little of the one slot they hold (config twin.trials_at_a_time).
        priority: FIRST
        conda:
            "../envs/esnap.yaml"
        params:
            at_a_time=config["twin"]["trials_at_a_time"],
            placements=DEPLOYMENT_BUDGET["placements"],
            trials_per_placement=DEPLOYMENT_BUDGET["trials_per_placement"],
            seed=config["seed"],
            sessions=config["sessions"],
            dt=config["twin"]["dt"],
            speed_mps=config["characterize"]["attach_speed_mps"],
            gate=asdict(LIMITS),
        script:
            "../workflow_scripts/twin_deployment.py"


if DEPLOYED:

    rule deploy_table:
        """Table II from the deployment recordings, and results/deployment/claims.csv."""
        input:
            index=f"{DEPLOYMENT_RAW}/index.csv",
            groups=f"{DEPLOYMENT_RAW}/groups",
            aborted=f"{DEPLOYMENT_RAW}/aborted.json",
            manifest=f"{DEPLOYMENT_DIR}/manifest.json",
            reference="reference/paper_values.yaml",
            code=imports("deploy_table"),
        output:
            trials=f"{DEPLOYMENT_DIR}/trials.csv",
            summary=f"{DEPLOYMENT_DIR}/summary.json",
            claims=f"{DEPLOYMENT_DIR}/claims.csv",
            csv="results/tables/table2_deployment.csv",
            md="results/tables/table2_deployment.md",
            tex="results/tables/table2_deployment.tex",
            html=report(
                "results/tables/table2_deployment.html",
                caption="../report/table2_deployment.rst",
                category=category("table2_deployment"),
            ),
        log:
            "logs/deployment/table.log",
        priority: reads_recordings
        conda:
            "../envs/esnap.yaml"
        params:
            bend_deg=DEPLOYMENT_CONFIG["preload_bend_deg"],
            fast_mps=DEPLOYMENT_CONFIG["fast_snap_mps"],
            protocol=protocol_params("sampling"),
        script:
            "../workflow_scripts/deploy_table.py"

    rule fig_deployment:
        """Fig. 7: a successful trial recorded (top) and predicted by the dynamics model (bottom)."""
        input:
            **SIMULATOR,
            trials=f"{DEPLOYMENT_DIR}/trials.csv",
            groups=f"{DEPLOYMENT_RAW}/groups",
            code=imports("fig_deployment"),
        output:
            pdf="results/figs/fig7_deployment.pdf",
            png=report(
                "results/figs/fig7_deployment.png",
                caption="../report/fig7_deployment.rst",
                category="Deployment",
            ),
        log:
            "logs/fig_deployment.log",
        benchmark:
            "benchmarks/deployment/fig.tsv"
        priority: reads_recordings
        conda:
            "../envs/esnap.yaml"
        resources:
            **SIMULATOR_RESOURCES,
        params:
            **SIMULATOR_PARAMS,
        script:
            "../workflow_scripts/fig_deployment.py"

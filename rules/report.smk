# Figures: one job per figure writes results/figs/; `figures` assembles results/figures/ from them,
# because Snakemake refuses outputs nested in another job's directory output.

FIGURES = [
    "fig0_data_overview",
    "fig1_system",
    "fig2_limits",
    "fig3_snap",
    "fig4_gates",
    "fig5_benchmark",
    "fig6_ablation",
    *(["fig7_deployment"] if DEPLOYED else []),
]


rule fig_data_overview:
    """The recordings at a glance: groups per evidence set and session, durations, tracking."""
    input:
        manifest="results/raw/manifest.json",
        code=imports("fig_data_overview"),
    output:
        pdf="results/figs/fig0_data_overview.pdf",
        png=report(
            "results/figs/fig0_data_overview.png",
            caption=caption("fig0_data_overview"),
            category=category("fig0_data_overview"),
        ),
    log:
        "logs/fig_data_overview.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/fig_data_overview.py"


rule figures:
    """Every paper figure, PDF and PNG, in one folder."""
    input:
        figs=expand("results/figs/{fig}.{ext}", fig=FIGURES, ext=("pdf", "png")),
        separation="results/lineage/separation.json",
        code=imports("figures"),
    output:
        directory("results/figures"),
    log:
        "logs/figures.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/figures.py"


rule fig_system:
    """Fig. 1: the arm, the primitive on a recorded strike, the shared policy's commands."""
    input:
        # the simulated rig's model rendered; with recordings of a real rig, panel (a) draws the strike
        render="results/twin/render.png" if TWIN else [],
        raw=raw_of(group_id=FIG1_GROUP),
        validated=validated(group_id=FIG1_GROUP),
        summary="results/policy/summary.json",
        evals=[e for e in POLICY_EVALUATIONS if Path(e).stem.startswith("shared_seed")],
        code=imports("fig_system"),
    output:
        pdf="results/figs/fig1_system.pdf",
        png=report(
            "results/figs/fig1_system.png",
            caption=caption("fig1_system"),
            category=category("fig1_system"),
        ),
    log:
        "logs/fig_system.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        group=FIG1_GROUP,
        protocol=protocol_params("sampling"),
    script:
        "../workflow_scripts/fig_system.py"


rule table_evidence:
    """Table I from the lineage: evidence sets and target sets, n, use and the proved separation."""
    input:
        separation="results/lineage/separation.json",
        index=raw_index(),
        split="results/splits/split.csv",
        # the deployment trials' own index (recorded after export): their row's n
        deployment_index=[f"{DEPLOYMENT_RAW}/index.csv"] if DEPLOYED else [],
        static="report/table1_evidence.rst",
        code=imports("table_evidence"),
    output:
        csv="results/tables/table1_evidence.csv",
        html=report(
            "results/tables/table1_evidence.html",
            caption=caption("table1_evidence"),
            category=category("table1_evidence"),
        ),
        md="results/tables/table1_evidence.md",
        tex="results/tables/table1_evidence.tex",
        caption=f"{CAPTIONS}/table1_evidence.rst",
    log:
        "logs/table_evidence.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        simulated=TWIN,
    script:
        "../workflow_scripts/table_evidence.py"


rule table_claims:
    """The claims ledger: every stage's claims, judged against the paper; the report's captions."""
    input:
        claims=claims_tables,
        artifacts=claims_artifacts,
        figs=expand("results/figs/{fig}.png", fig=FIGURES),
        separation="results/lineage/separation.json",
        reference="reference/paper_values.yaml",
        captions=expand("report/{fig}.rst", fig=FIGURES),
        docs=sorted(glob.glob("docs/*.md")),
        index=raw_index(),
        # the deployment trials' evidence set, for the Table II numbers' recordings
        trials=[f"{DEPLOYMENT_RAW}/index.csv"] if DEPLOYED else [],
        split="results/splits/split.csv",
        manifest="results/raw/manifest.json",
        code=imports("table_claims"),
    output:
        csv="results/tables/claims.csv",
        html=report(
            "results/tables/claims.html",
            caption=caption("claims"),
            category="Claims ledger",
        ),
        md="results/tables/claims.md",
        captions=expand(f"{CAPTIONS}/{{fig}}.rst", fig=FIGURES),
        caption=f"{CAPTIONS}/claims.rst",
    log:
        "logs/table_claims.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        simulated=TWIN,
    script:
        "../workflow_scripts/table_claims.py"

# Figures: one job per figure writes results/figs/; `figures` assembles results/figures/ from them,
# because Snakemake refuses outputs nested in another job's directory output.

FIGURES = [
    "fig0_data_overview",
    "fig2_limits",
    "fig3_snap",
    "fig4_gates",
    "fig5_benchmark",
    "fig6_ablation",
    "fig7_deployment",
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
            caption="../report/fig0_data_overview.rst",
            category="Data",
        ),
    log:
        "logs/fig_data_overview.log",
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

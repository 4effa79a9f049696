# embodied-snap: from raw rig recordings to every figure of the paper, with lineage.
# Targets: all (default), results/figures; after them, robustness (the architecture benchmark's
# variants), sensitivity (its starting points) and landscape (the per-target optimum).
from snakemake.utils import min_version, validate

min_version("9.0")


configfile: "config.yaml"


# A config that breaks the schema stops here in one line naming the key and the rule, as `esnap`
# says it (embodied_snap/schemacheck.py), not with the whole schema (nor Snakemake's frame around it).
try:
    validate(config, "schemas/config.schema.yaml")
except WorkflowError as e:
    import sys

    sys.path.insert(0, workflow.basedir)
    from embodied_snap.schemacheck import error_line

    sys.exit(f"error: config: {error_line(e)}")


include: "rules/common.smk"


wildcard_constraints:
    shard=r"[a-z_]+-\d+",
    role="train|validation|sealed",


if config["raw_data"]["source"] == "twin":

    include: "rules/acquire.smk"


include: "rules/data.smk"
include: "rules/characterize.smk"
include: "rules/dynamics.smk"
include: "rules/policy.smk"
include: "rules/ablation.smk"
include: "rules/robustness.smk"
include: "rules/sensitivity.smk"
include: "rules/deploy.smk"
include: "rules/lineage.smk"
include: "rules/report.smk"


# Every product of the run; the RO-Crate comes after all of them (a new stage adds its own here).
# The stages' rule files are read in any order: each reads only rules/common.smk and its own names
# (tests/test_rule_files.py).
PRODUCTS = [
    "results/figures",
    "results/raw/manifest.json",
    *expand(RESAMPLED_SHARD, shard=SHARDS),
    "results/lineage/separation.json",
    "results/lineage/prov.json",
    *claims_tables(),
    "results/tables/table1_evidence.csv",
    "results/tables/claims.csv",
    *(
        f"results/tables/table2_deployment.{ext}"
        for ext in ("csv", "md", "tex")
        if DEPLOYED
    ),
    "results/deployment/manifest.json",
    # the simulated rig's own check against its truth (rules/acquire.smk)
    *(["results/twin/validation.json"] if TWIN else []),
]


# The architecture question's products, each its own target after `all` (at the paper budget each
# takes most of an hour on two cores): the crate lists them once they exist.
AFTER_ALL = {
    "robustness": [
        "results/robustness/variants.csv",
        "results/figs/figS1_robustness.pdf",
    ],
    "sensitivity": [
        "results/sensitivity/starts.csv",
        "results/figs/figS2_sensitivity.pdf",
    ],
    "landscape": [
        "results/landscape/summary.json",
        "results/landscape/architectures.csv",
    ],
}


rule all:
    default_target: True
    input:
        PRODUCTS,
        "results/crate/ro-crate-metadata.json",


rule robustness:
    """The architecture benchmark's robustness variants (docs/policy.md): about an hour more on two
    cores at the paper budget, so not part of `all`."""
    input:
        AFTER_ALL["robustness"],


rule sensitivity:
    """The architecture benchmark from other starting points (docs/policy.md, "Starting point")."""
    input:
        AFTER_ALL["sensitivity"],


rule landscape:
    """What the landscape allows: the per-target optimum and the architectures against it."""
    input:
        AFTER_ALL["landscape"],


rule crate:
    """The run as a Workflow Run RO-Crate (Provenance Run Crate), after every other product, those
    of the targets after `all` too once they exist (a later `snakemake all` then rewrites the crate).
    """
    input:
        lambda wc: PRODUCTS
        + [f for fs in AFTER_ALL.values() for f in fs if Path(f).exists()],
        code=imports("crate"),
    output:
        "results/crate/ro-crate-metadata.json",
    log:
        "logs/crate.log",
    conda:
        "envs/esnap.yaml"
    script:
        "workflow_scripts/crate.py"

"""What each evidence set may feed (docs/design.md section 3), as an allow list: the one place to
change it.

A source is an evidence set, a split role of the dynamics corpus, or a file (the simulated rig's
ground truth, a simulated target set). Data of a source *reaches* a job when it flows to the job
through any chain of jobs. Every job a source reaches must be named in its `may_feed`, by rule name
or by one wildcard instance `rule(k=v)`; anything else is a violation. Every rule of the workflow
must be named somewhere here (as bookkeeping, a gate, a target, a source rule or in some
`may_feed`): a rule nothing names is a violation too, so a new rule needs a decision here first.
"""

from __future__ import annotations

from dataclasses import dataclass

# Jobs that carry only metadata about recordings (checks, manifest, index, split table, the
# lineage itself, the overview figure of the recordings): data does not flow *through* them, or
# the raw manifest, which reads every group, would make every group reach everything after it.
BOOKKEEPING = frozenset({
    "validate_shard", "validate_index", "validate_sealed", "raw_manifest", "twin_index", "split",
    "check_separation", "check_separation_dag", "prov_export", "fig_data_overview",
    # the paper's build products that read only metadata: Table I (the index, the split and the
    # separation proof), the arm's render (the simulator's model, no recording), the RO-Crate
    "table_evidence", "twin_render", "crate",
})
# Jobs whose outputs are statements about the whole run: reports list them as inputs only to run
# after them, so `esnap audit` lists them in a chain but does not descend into them.
GATES = frozenset({"check_separation", "check_separation_dag", "prov_export", "crate"})
# Rules that only name other targets and write nothing.
TARGETS = frozenset({"all", "robustness", "sensitivity", "landscape"})
# Rules whose `shard` wildcard marks a job as reading one shard's groups: where the walk starts.
SOURCE_RULES = frozenset({"twin_acquire", "validate_shard", "resample_shard"})
# Rules that write a file source.
FILE_WRITERS = frozenset({"twin_truth", "policy_targets", "ablation_targets", "robustness_targets",
                          "twin_deployment"})

# Reports of each stage: tables and figures, the folder that gathers the figures, and the claims
# ledger that gathers every stage's claims (with the report captions it writes).
LEDGER = "table_claims"
CHAR_REPORTS = ("table_characterize_claims", "fig_limits", "fig_snap", "twin_validation", "figures", LEDGER)
# The GRU seeds: a job each, or all in one (config dynamics.seeds_in_one_job).
DYN_TRAIN = ("dynamics_train", "dynamics_train_seeds")
DYN_REPORTS = ("table_dynamics_claims", "fig_gates", "figures", LEDGER)
# The searches: a job per run, or every run in one (config policy.batch_runs).
POLICY_SEARCH = ("policy_search", "policy_search_lockstep")
POLICY_RUNS = (*POLICY_SEARCH, "policy_evaluate", "policy_fixed", "policy_summary")
# Fig. 1 shows the selected policy's commands for one evaluation target.
POLICY_REPORTS = ("fig_benchmark", "table_policy_claims", "figures", "fig_system", LEDGER)
# The release-rule ablation (paper V-A, V-B, Fig. 6): everything after the offset fit, and the fit.
ABLATION_EVAL = ("ablation_rules", "ablation_summary", "fig_ablation", "table_ablation_claims", "figures", LEDGER)
ABLATION_RUNS = ("ablation_offsets", "ablation_bend", "ablation_perturb", *ABLATION_EVAL)
# The architecture benchmark's robustness variants (rules/robustness.smk): runs on their own targets
# or continued from the benchmark's, evaluated, summarised.
ROBUSTNESS_RUNS = ("robustness_search_uniform", "robustness_search_longer", "robustness_fixed",
                   "robustness_evaluate")
ROBUSTNESS_REPORTS = ("robustness_summary", "fig_robustness", "table_robustness_claims")
ROBUSTNESS = (*ROBUSTNESS_RUNS, *ROBUSTNESS_REPORTS)
# The benchmark from other starting points (rules/sensitivity.smk): runs on the benchmark's targets,
# evaluated, summarised (the summary reads the evaluation targets' features for the slope probe);
# and the landscape: the per-target optimum on the first evaluation targets, against the policies.
SENSITIVITY_REPORTS = ("sensitivity_summary", "fig_sensitivity", "table_sensitivity")
SENSITIVITY = ("sensitivity_search", "sensitivity_evaluate", *SENSITIVITY_REPORTS)
LANDSCAPE = ("landscape_optimum", "landscape_summary")
# Deployment (paper VI): the manifest exported from the selected policy, the trials that run it,
# and its reports. Everything that fed the policy reaches all of these through the manifest.
DEPLOY_REPORTS = ("deploy_table", "fig_deployment", "figures", LEDGER)
DEPLOY_RULES = ("deploy_manifest", "twin_deployment", *DEPLOY_REPORTS)
# Everything that uses the GRU models (trained on train, selected on validation windows).
MODEL_USERS = (
    "dynamics_validate", "dynamics_sealed_eval", "dynamics_gate", *POLICY_RUNS, *DYN_REPORTS,
    *POLICY_REPORTS, *ABLATION_RUNS, *ROBUSTNESS, *SENSITIVITY, *LANDSCAPE, *DEPLOY_RULES,
)


@dataclass(frozen=True)
class Source:
    may_feed: tuple[str, ...]
    rule: str  # the sentence of docs/design.md section 3 a violation breaks
    held_out: bool = False  # kept out of every model fit (exported as esnap:held_out)
    # File sources: the only rules that may read the file itself (the separation proof reads the
    # target sets to show they are disjoint; it writes no data).
    readers: tuple[str, ...] = ()


POLICY: dict[str, Source] = {
    "servo_calibration": Source(
        ("characterize_kinematics", "characterize_servo", "characterize_release", "characterize_heldbase",
         *CHAR_REPORTS, *DEPLOY_RULES),
        "servo_calibration may feed tendon kinematics, the servo rate fit and the rate ceilings (the "
        "manifest's calibration), never the dynamics model or policies"),
    "attachment": Source(
        ("characterize_attachment", "twin_phenomena", "fig_system", *CHAR_REPORTS),
        "attachment may feed the speed/angle attachment model (and Fig. 1's example strike), never the "
        "dynamics model or policies"),
    "release_mode": Source(
        ("characterize_release", "twin_phenomena", *CHAR_REPORTS),
        "release_mode may feed Fig. 2b, never the dynamics model"),
    "delay_sweep": Source(
        ("characterize_delay_sweep", "twin_phenomena", "dynamics_gate", *CHAR_REPORTS, *DYN_REPORTS),
        "delay_sweep may feed the timing set and the timing/dynamics gates, never any model fit",
        held_out=True),
    "held_base": Source(
        ("characterize_heldbase", *CHAR_REPORTS),
        "held_base may feed the trigger-detection comparison, never the dynamics model or policies"),
    # Recorded after export (raw_data/deployment/, a tree of its own): a file source read only by
    # Table II, Fig. 7, the separation proof (which also shows the manifest's inputs unchanged; its
    # DAG half, because the trials' index brings the reports of the trials into the DAG),
    # Table I, which counts the trials, and the ledger, which names each Table II number's trials.
    "deployment": Source(
        DEPLOY_REPORTS,
        "deployment may feed Table II and Fig. 7, nothing upstream of the manifest", held_out=True,
        readers=("deploy_table", "fig_deployment", "check_separation", "check_separation_dag", "table_evidence",
                 LEDGER)),
    # The dynamics corpus by split role (440 / 78 / 20).
    "train": Source(
        ("windows(role=train)", *DYN_TRAIN, "characterize_snap", "dynamics_hold", "policy_workspace",
         "policy_targets", "ablation_targets", "robustness_targets", *MODEL_USERS, *CHAR_REPORTS),
        "train groups stay in the training windows; the hold bank and snap classifier use them"),
    "validation": Source(
        ("windows(role=validation)", *DYN_TRAIN, "dynamics_persistence", *MODEL_USERS),
        "validation groups feed model selection and the validation errors; never the training "
        "windows, the hold bank or the snap classifier", held_out=True),
    "sealed": Source(
        ("windows(role=sealed)", "dynamics_sealed_eval", "table_dynamics_claims", LEDGER),
        "sealed groups may feed only the sealed windows, the single sealed evaluation and its table "
        "(and the claims ledger that gathers it)",
        held_out=True),
    # Files. The twin's truth: `raw` is replaced by the configured raw directory.
    "twin_truth": Source(
        ("twin_validation",), "only twin_validation reads the simulated rig's ground truth",
        held_out=True, readers=("twin_validation",)),
    "results/policy/targets_selection.parquet": Source(
        (*POLICY_RUNS, *POLICY_REPORTS, *ABLATION_RUNS, *ROBUSTNESS, *SENSITIVITY, "landscape_summary",
         *DEPLOY_RULES),
        "the selection targets select policies and the fixed primitive (and so the deployed policy), nothing else",
        readers=(*POLICY_SEARCH, "policy_fixed", "robustness_search_longer", "sensitivity_search",
                 "check_separation")),
    "results/policy/targets_evaluation.parquet": Source(
        ("policy_evaluate", "policy_fixed", "policy_summary", *POLICY_REPORTS, "ablation_bend", "ablation_perturb",
         "ablation_summary", "fig_ablation", "table_ablation_claims", "robustness_evaluate",
         *ROBUSTNESS_REPORTS, "sensitivity_evaluate", *SENSITIVITY_REPORTS, *LANDSCAPE, LEDGER),
        "the evaluation targets are read only by the final evaluation, after selection (and the ablation's "
        "analyses of the selected policy on them, the variants' and starts' evaluations, and the "
        "per-target optimum that bounds them)",
        held_out=True, readers=("policy_evaluate", "policy_fixed", "ablation_bend", "ablation_perturb",
                                "robustness_evaluate", "sensitivity_evaluate", "sensitivity_summary",
                                *LANDSCAPE, "check_separation")),
    "results/ablation/targets_offset.parquet": Source(
        ("ablation_offsets", *ABLATION_EVAL),
        "the offset targets fit the event offsets of the release rules, nothing else",
        readers=("ablation_offsets", "check_separation")),
    "results/ablation/targets_release.parquet": Source(
        ABLATION_EVAL,
        "the release-evaluation targets are read only by the rule comparison, never by an offset fit",
        held_out=True, readers=("ablation_rules", "check_separation")),
    # The robustness variants' targets (uniform over the workspace; a continued run's training).
    "results/robustness/uniform/targets_training.parquet": Source(
        ("robustness_search_uniform", "robustness_evaluate", *ROBUSTNESS_REPORTS),
        "the uniform training targets train the uniform variant's runs, nothing else",
        readers=("robustness_search_uniform", "check_separation")),
    "results/robustness/uniform/targets_selection.parquet": Source(
        ("robustness_search_uniform", "robustness_fixed", "robustness_evaluate", *ROBUSTNESS_REPORTS),
        "the uniform selection targets select the uniform variant's policies and fixed primitive",
        readers=("robustness_search_uniform", "robustness_fixed", "check_separation")),
    "results/robustness/uniform/targets_evaluation.parquet": Source(
        ("robustness_fixed", "robustness_evaluate", *ROBUSTNESS_REPORTS),
        "the uniform evaluation targets are read only by the uniform variant's final evaluation",
        held_out=True, readers=("robustness_fixed", "robustness_evaluate", "check_separation")),
    "results/robustness/targets_extension.parquet": Source(
        ("robustness_search_longer", "robustness_evaluate", *ROBUSTNESS_REPORTS),
        "the generations a continued run adds train on these targets, nothing else reads them",
        readers=("robustness_search_longer", "check_separation")),
}
FILE_SOURCES = tuple(k for k, v in POLICY.items() if v.readers)
WINDOW_ROLES = ("train", "validation", "sealed")
TARGET_SETS = ("training", "selection", "evaluation")
# Every simulated target set, by file: all pairwise disjoint (checks._target_violations).
TARGET_FILES = (*(f"results/policy/targets_{n}.parquet" for n in TARGET_SETS),
                "results/ablation/targets_offset.parquet", "results/ablation/targets_release.parquet",
                *(f"results/robustness/uniform/targets_{n}.parquet" for n in TARGET_SETS),
                "results/robustness/targets_extension.parquet")


def label(rule: str, wildcards: dict) -> str:
    return f"{rule}({','.join(f'{k}={v}' for k, v in sorted(wildcards.items()))})" if wildcards else rule


def _names(entry: str) -> str:
    return entry.split("(", 1)[0]


def named_rules() -> frozenset[str]:
    """Every rule this policy names."""
    out = set(BOOKKEEPING | GATES | TARGETS | SOURCE_RULES | FILE_WRITERS)
    for s in POLICY.values():
        out |= {_names(e) for e in s.may_feed + s.readers}
    return frozenset(out)


def may_feed(source: str, rule: str, wildcards: dict) -> bool:
    """Does the policy allow data of `source` to reach this job? Bookkeeping and the source rules
    (where a shard's recordings enter) are always allowed; a source without a policy row (the
    unsplit dynamics corpus) is judged by its split roles."""
    p = POLICY.get(source)
    if p is None or rule in BOOKKEEPING or rule in SOURCE_RULES:
        return True
    lab = label(rule, wildcards)
    return any(e == rule or e == lab for e in p.may_feed)


# Each stage's reports (tables, figures, the ledger), as the rows above name them: a row that names
# one of these whole feeds the stage's reports, not one report in particular (`needs`).
REPORTS = (CHAR_REPORTS, DYN_REPORTS, POLICY_REPORTS, ROBUSTNESS_REPORTS, SENSITIVITY_REPORTS, DEPLOY_REPORTS,
           ABLATION_EVAL[2:])


def needs(evidence_set: str) -> list[str]:
    """The rules that need an evidence set's recordings (`esnap validate --partial` names them for
    a set a tree lacks): those its policy row lets its data feed, for the dynamics corpus those of
    any of its split roles, less the reports of a stage the row names whole (REPORTS: they come
    after the fits); a report a row names on its own (Fig. 1's attachment trial) stays. The
    separation proof holds the workflow to these rows (`esnap check-separation`)."""
    rows = [POLICY[evidence_set]] if evidence_set in POLICY else [POLICY[r] for r in WINDOW_ROLES]
    names = {_names(e) for p in rows for e in p.may_feed}
    return sorted(names - {r for t in REPORTS if set(t) <= names for r in t})


def held_out(role: str, evidence_set: str) -> bool:
    """Validation and sealed groups, and every evidence set that must never feed a model fit."""
    p = POLICY.get(role) or POLICY.get(evidence_set)
    return bool(p and p.held_out)

# Hardware characterisation (paper section III and V-C; docs/design.md section 4, step 4): one rule and one
# artifact per fit. Inputs are exactly the recordings a fit may see (raw_of), the validation
# records of their shards, and the package modules the fit imports (code), so the DAG shows what
# fed each number.

CHARACTERIZE_DIR = "results/characterize"


CALIBRATION = dict(evidence_set="servo_calibration")
CALIBRATION_GROUPS = sorted(select(**CALIBRATION).group_id)
HELD_GROUPS = sorted(select(evidence_set="held_base").group_id)
SNAP_GROUPS = dict(evidence_set="dynamics", category="characterisation", role="train")


rule characterize_kinematics:
    """Eq. 1: lever ratios d_p/k by quantile regression on the taut envelope; travel per tick."""
    input:
        raw=raw_of(**CALIBRATION),
        valid=validated(**CALIBRATION),
        code=imports("characterize_kinematics"),
    output:
        f"{CHARACTERIZE_DIR}/kinematics.json",
    log:
        "logs/characterize/kinematics.log",
    benchmark:
        "benchmarks/characterize/kinematics.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=CALIBRATION_GROUPS,
        quantile=config["characterize"]["envelope_quantile"],
        tendon_radius_m=config["rig"]["tendon_radius_m"],
        protocol=protocol_params("sampling"),
    script:
        "../workflow_scripts/characterize_kinematics.py"


rule characterize_servo:
    """First-order fit over all calibration bursts; Eq. 2 ceilings from the rated speed (config)."""
    input:
        raw=raw_of(**CALIBRATION),
        valid=validated(**CALIBRATION),
        kinematics=f"{CHARACTERIZE_DIR}/kinematics.json",
        code=imports("characterize_servo"),
    output:
        f"{CHARACTERIZE_DIR}/servo.json",
    log:
        "logs/characterize/servo.log",
    benchmark:
        "benchmarks/characterize/servo.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=CALIBRATION_GROUPS,
        protocol=protocol_params("rig"),
    script:
        "../workflow_scripts/characterize_servo.py"


rule characterize_release:
    """Peak tip speed per release mode; section rates at the operating point over the ceilings."""
    input:
        raw=raw_of(evidence_set="release_mode"),
        valid=validated(evidence_set="release_mode"),
        servo=f"{CHARACTERIZE_DIR}/servo.json",
        code=imports("characterize_release"),
    output:
        f"{CHARACTERIZE_DIR}/release.json",
    log:
        "logs/characterize/release.log",
    benchmark:
        "benchmarks/characterize/release.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=select(evidence_set="release_mode")[
            ["group_id", "category", "session"]
        ].to_dict("records"),
        protocol=protocol_params("sampling", "rig", "thresholds"),
    script:
        "../workflow_scripts/characterize_release.py"


rule characterize_attachment:
    """Speed/cup-tilt logistic model, session-grouped CV AUC; the 1 m/s and 150 mm counts."""
    input:
        raw=raw_of(evidence_set="attachment"),
        valid=validated(evidence_set="attachment"),
        code=imports("characterize_attachment"),
    output:
        f"{CHARACTERIZE_DIR}/attachment.json",
    log:
        "logs/characterize/attachment.log",
    benchmark:
        "benchmarks/characterize/attachment.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=select(evidence_set="attachment")[
            ["group_id", "category", "session"]
        ].to_dict("records"),
        protocol=protocol_params("sampling", "rig", "thresholds"),
    script:
        "../workflow_scripts/characterize_attachment.py"


rule characterize_snap:
    """P_snap(rho1, rho2) from the training-split characterisation groups only: the artifact the
    policy reward loads."""
    input:
        raw=raw_of(**SNAP_GROUPS),
        valid=validated(**SNAP_GROUPS),
        code=imports("characterize_snap"),
    output:
        f"{CHARACTERIZE_DIR}/snap.json",
    log:
        "logs/characterize/snap.log",
    benchmark:
        "benchmarks/characterize/snap.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=select(**SNAP_GROUPS)[["group_id", "category", "session"]].to_dict(
            "records"
        ),
        protocol=protocol_params("sampling", "rig", "thresholds"),
    script:
        "../workflow_scripts/characterize_snap.py"


rule characterize_delay_sweep:
    """The held-out delay sweep: speed and approach over tau, attach counts, supported interval."""
    input:
        raw=raw_of(evidence_set="delay_sweep"),
        valid=validated(evidence_set="delay_sweep"),
        code=imports("characterize_delay_sweep"),
    output:
        f"{CHARACTERIZE_DIR}/delay_sweep.json",
    log:
        "logs/characterize/delay_sweep.log",
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=select(evidence_set="delay_sweep")[
            ["group_id", "category", "session"]
        ].to_dict("records"),
        protocol=protocol_params("sampling", "rig"),
    script:
        "../workflow_scripts/characterize_delay_sweep.py"


rule characterize_heldbase:
    """Held-base trials: base, neighbour, servo-residual detectors and the best clock."""
    input:
        raw=raw_of(evidence_set="held_base"),
        valid=validated(evidence_set="held_base"),
        servo=f"{CHARACTERIZE_DIR}/servo.json",
        code=imports("characterize_heldbase"),
    output:
        f"{CHARACTERIZE_DIR}/heldbase.json",
    log:
        "logs/characterize/heldbase.log",
    benchmark:
        "benchmarks/characterize/heldbase.tsv"
    priority: reads_recordings
    conda:
        "../envs/esnap.yaml"
    params:
        raw=raw_dir,
        groups=HELD_GROUPS,
        detectors=config["characterize"]["heldbase"],
        protocol=protocol_params("sampling", "thresholds"),
    script:
        "../workflow_scripts/characterize_heldbase.py"


# A table of every fit, the held-out delay sweep included: named table_* (a report, like the
# figures), because the separation policy lets the delay sweep reach no characterize_* rule but
# its own.
rule table_characterize_claims:
    """Every number of section III and V-C beside the paper's value."""
    input:
        kinematics=f"{CHARACTERIZE_DIR}/kinematics.json",
        servo=f"{CHARACTERIZE_DIR}/servo.json",
        release=f"{CHARACTERIZE_DIR}/release.json",
        attachment=f"{CHARACTERIZE_DIR}/attachment.json",
        snap=f"{CHARACTERIZE_DIR}/snap.json",
        delay_sweep=f"{CHARACTERIZE_DIR}/delay_sweep.json",
        heldbase=f"{CHARACTERIZE_DIR}/heldbase.json",
        reference="reference/paper_values.yaml",
        code=imports("characterize_claims"),
    output:
        f"{CHARACTERIZE_DIR}/claims.csv",
    log:
        "logs/characterize/claims.log",
    conda:
        "../envs/esnap.yaml"
    script:
        "../workflow_scripts/characterize_claims.py"


rule fig_limits:
    """Fig. 2: rate ceilings, release speed distributions, attachment over speed and tilt."""
    input:
        kinematics=f"{CHARACTERIZE_DIR}/kinematics.json",
        servo=f"{CHARACTERIZE_DIR}/servo.json",
        release=f"{CHARACTERIZE_DIR}/release.json",
        attachment=f"{CHARACTERIZE_DIR}/attachment.json",
        code=imports("fig_limits"),
    output:
        pdf="results/figs/fig2_limits.pdf",
        png=report(
            "results/figs/fig2_limits.png",
            caption=caption("fig2_limits"),
            category=category("fig2_limits"),
        ),
    log:
        "logs/fig_limits.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    params:
        seed=config["seed"],
        protocol=protocol_params("thresholds"),
    script:
        "../workflow_scripts/fig_limits.py"


rule fig_snap:
    """Fig. 3: P_snap map with the operating point; speed, approach and attachment over delay."""
    input:
        snap=f"{CHARACTERIZE_DIR}/snap.json",
        delay_sweep=f"{CHARACTERIZE_DIR}/delay_sweep.json",
        code=imports("fig_snap"),
    output:
        pdf="results/figs/fig3_snap.pdf",
        png=report(
            "results/figs/fig3_snap.png",
            caption=caption("fig3_snap"),
            category=category("fig3_snap"),
        ),
    log:
        "logs/fig_snap.log",
    priority: DRAW
    conda:
        "../envs/esnap.yaml"
    params:
        protocol=protocol_params("thresholds"),
    script:
        "../workflow_scripts/fig_snap.py"

"""The deployment manifest (paper VI): the selected shared policy and everything `esnap deploy`
needs, with the sha256 of every input, validated against schemas/deployment_manifest.schema.json."""

import json
import sys

import jsonschema

from embodied_snap.deploy import manifest as MF
from embodied_snap.io import write_json
from embodied_snap.lineage.records import code_version, tracked
from embodied_snap.policy.analysis import selected_seed

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    I, P = snakemake.input, snakemake.params
    runs = {r: json.load(open(r)) for r in I.runs}
    seed = selected_seed(list(runs.values()))  # the policy stage's selection: highest selection reward
    run_path = next(p for p, r in runs.items() if r["seed"] == seed)
    inputs = {"policy_run": run_path, "workspace": I.workspace, "servo_fit": I.servo, "hold_bank": I.bank,
              "snap_model": I.snap, **{f"dynamics_model_{k}": m for k, m in enumerate(I.models)},
              **{f"search_run_{json.load(open(p))['seed']}": p for p in I.runs if p != run_path}}
    lineage = dict(
        selected_by=f"highest reward on the selection targets among {len(runs)} shared runs (policy_search)",
        fed_by={"policy_run": "policy_search: CMA-ES on the GRU ensemble, hold bank, P_snap and workspace",
                "workspace": "policy_workspace: training-split dynamics groups",
                "hold_bank": "dynamics_hold: training-split dynamics groups",
                "snap_model": "characterize_snap: training-split dynamics groups",
                "dynamics_model": "dynamics_train: training windows, selected on validation windows",
                "servo_fit": "characterize_servo: servo_calibration groups"},
        retraining="none after export: every trial's meta.json carries this manifest's checksum")
    man = MF.build(inputs=inputs, run=runs[run_path], workspace=json.load(open(I.workspace)),
                   servo_fit=json.load(open(I.servo)),
                   cfg=dict(P.deployment, policy=P.policy, n_placements=P.placements), proto=P.protocol,
                   code_version=code_version("."), lineage=lineage)
    jsonschema.validate(man, json.load(open(I.schema)))
    print(f"selected shared seed {seed}; checksum {man['checksum']}", file=sys.stderr)
    write_json(man, snakemake.output[0])

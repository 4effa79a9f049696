"""Fig. 6 and claims statistics of the ablation: release rules, tolerance sweep, bend point,
perturbation."""

import json
import sys

from embodied_snap.ablation import summary
from embodied_snap.io import read_parquet, write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.policy.analysis import REPORT_TOL_M

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    P, I = snakemake.params, snakemake.input
    R = P.reward
    offsets = json.load(open(I.offsets))
    res = {
        "report_tolerance_m": REPORT_TOL_M,
        "n_offset_targets": offsets["n_targets"],
        "offsets_s": {r: v["delta_s"] for r, v in offsets["rules"].items()},
        "rules": summary.rules(read_parquet(I.rules), REPORT_TOL_M, R["d_f_m"], R["v_min_sim_mps"], P.seed,
                               P.n_boot),
        "sweep": summary.sweep({"learned": read_parquet(I.learned), "fixed": read_parquet(I.fixed)},
                               P.tolerances, R["d_f_m"], R["v_min_sim_mps"]),
        "bend": {k: v for k, v in json.load(open(I.bend)).items() if not k.endswith("correlations")},
        "perturbation": json.load(open(I.perturb))["scales"],
    }
    print(json.dumps(res["rules"], indent=1), file=sys.stderr)
    write_json(res, snakemake.output[0])

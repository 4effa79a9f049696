"""Table II (paper VI) from the deployment recordings (embodied_snap/deploy/table2.py), and the
deployment claims beside the paper's values."""

import json
import sys

import pandas as pd

from embodied_snap.deploy import table2 as D
from embodied_snap.io import write_json
from embodied_snap.lineage.records import tracked
from embodied_snap.paper import html
from embodied_snap.protocol import from_params

sys.stderr = open(snakemake.log[0], "w")
with tracked(snakemake):
    I, O, P = snakemake.input, snakemake.output, snakemake.params
    man = json.load(open(I.manifest))
    raw = I.groups.rsplit("/groups", 1)[0]
    index = pd.read_csv(I.index)
    aborted = json.load(open(I.aborted))
    trials = pd.DataFrame([D.trial(raw, g, man, from_params(P.protocol).sampling.max_gap_s) for g in index.group_id],
                          columns=None if len(index) else ["group_id", "placement", "v_peak_mps", "retrieved",
                                                           "attached", "open_loop", "s2_bend_increase_deg"])
    trials.to_csv(O.trials, index=False, lineterminator="\n")
    s = D.summarize(trials, aborted["planned"], len(man["placements"]), P.bend_deg, P.fast_mps,
                    len(aborted["aborted"]))
    s["recordings"] = dict(used=sorted(trials.group_id) if len(trials) else [],
                           dropped={a["group_id"]: a["cause"] for a in aborted["aborted"]})
    write_json(s, O.summary)
    t2 = D.table2(s, P.bend_deg, P.fast_mps, I.reference)
    print(t2.to_string(), file=sys.stderr)
    t2.to_csv(O.csv, index=False, lineterminator="\n")
    open(O.md, "w").write(D.markdown(t2))
    open(O.tex, "w").write(D.latex(t2))
    open(O.html, "w").write(html.table("Table II: deployment of the frozen shared policy",  # the report's view
                                       f"{len(trials)} trials recorded, {len(aborted['aborted'])} aborted or rejected.",
                                       list(t2.columns), t2.to_dict("records")))
    claims = D.claims((O.summary, s), (I.manifest, man), I.reference)
    pd.DataFrame(claims).to_csv(O.claims, index=False, lineterminator="\n")

"""Table II (paper VI): the deployment trials, read with the characterisation code's loaders and
motion-capture features (deployment imports characterisation, never the other way).

Per trial, from its recordings: the S2 bend increase over the preload (mocap frames, mocap.py),
the peak tip speed after the release began (trials.features), the observed labels (attached,
retrieved), and whether every goal the servos got is the goal the manifest gives for the trial's
target (the open-loop property: nothing read back changed a command). A trial recorded under
another manifest stops the table with one line. Run by the workflow (pandas): not loaded by
`esnap deploy` on the lab PC.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..characterize import load, trials
from ..characterize import mocap as M
from ..reference import claim_rows, fmt, paper_column
from . import commands as C


class DeploymentError(ValueError):
    pass


def trial(raw, gid: str, man: dict, max_gap_s: float) -> dict:
    mc, sv, meta = load.group(raw, gid)
    if meta.get("manifest_sha256") != man["checksum"]:
        raise DeploymentError(f"{raw}/groups/{gid}/meta.json: group {gid}: recorded under manifest "
                              f"{str(meta.get('manifest_sha256'))[:12]}, not {man['checksum'][:12]} "
                              "(rule: deployment trials run the exported manifest)")
    lab, prog = meta["labels"], meta["program"]
    t = mc.t.to_numpy()
    th, _ = M.section_bends(mc, max_gap_s)
    hang = np.nanmedian(th[t < lab["t_preload"], 1])
    pre = np.nanmax(th[(t >= lab["t_preload"]) & (t <= lab["t_slack"]), 1])
    f = trials.features(mc, meta, man["primitive"]["end_effector_m"], max_gap_s)  # the exported arm's end effector
    plan = C.plan(man, prog["target_m"])
    logged = sv[[f"goal_{i}" for i in range(1, 10)]].to_numpy()
    open_loop = logged.shape == plan["goals"].shape and bool(np.array_equal(logged, plan["goals"]))
    return dict(group_id=gid, placement=int(prog["placement"]), session=meta["session"],
                s2_bend_increase_deg=float(np.degrees(pre - hang)), v_peak_mps=f["v_peak"],
                closest_m=f["closest_m"], tilt_deg=f["tilt_deg"], attached=bool(lab["attached"]),
                retrieved=bool(lab["retrieved"]), open_loop=open_loop,
                **{k: prog[k] for k in ("rho1", "rho2", "rho3", "s3", "dphi", "tau", "bearing")})


def summarize(df: pd.DataFrame, n_planned: int, n_placements: int, bend_deg: float, fast_mps: float,
              aborted: int) -> dict:
    if df.empty:  # every trial aborted: counts are zero, the speed statistics undefined
        df = pd.DataFrame(columns=["placement", "s2_bend_increase_deg", "v_peak_mps", "retrieved", "attached",
                                   "open_loop"]).astype({"retrieved": bool, "attached": bool, "open_loop": bool})
    v = df.v_peak_mps.to_numpy(float)
    q1, med, q3 = np.percentile(v, [25, 50, 75]) if len(v) else (np.nan,) * 3
    return dict(
        n_trials=n_planned, n_recorded=len(df), n_aborted=aborted, n_placements=n_placements,
        preload_reached=int((df.s2_bend_increase_deg >= bend_deg).sum()),
        fast_snap=int((df.v_peak_mps >= fast_mps).sum()),
        peak_speed_median_mps=float(med), peak_speed_iqr_mps=[float(q1), float(q3)],
        peak_speed_max_mps=float(np.max(v)) if len(v) else np.nan,
        retrieved=int(df.retrieved.sum()), attached=int(df.attached.sum()),
        placements_retrieved=int(df[df.retrieved].placement.nunique()),
        online_correction=("no complete trial" if df.empty else "none" if bool(df.open_loop.all())
                           else "goals differ from the manifest's schedule"),
    )


def table2(s: dict, bend_deg: float, fast_mps: float, path=None) -> pd.DataFrame:
    """Table II rows: evidence, criterion, our result, the paper's (reference/paper_values.yaml)."""
    n, k = s["n_trials"], s["n_placements"]
    iqr = s["peak_speed_iqr_mps"]
    paper = paper_column("deployment", *([path] if path else []))

    def p(key):
        return fmt(paper[key])

    rows = [
        ("Preload reached", f"S2 bend increase >= {bend_deg:g} deg", f"{s['preload_reached']}/{n}",
         f"{p('preload_reached')}/{p('n_trials')}"),
        ("Fast snap produced", f"Peak tip speed >= {fast_mps:g} m/s", f"{s['fast_snap']}/{n}",
         f"{p('fast_snap')}/{p('n_trials')}"),
        ("Snap-speed distribution", "Median [IQR]",
         f"{s['peak_speed_median_mps']:.2f} m/s [{iqr[0]:.2f}-{iqr[1]:.2f}]",
         f"{p('peak_speed_median_mps')} m/s [{'-'.join(fmt(x) for x in paper['peak_speed_iqr_mps'])}]"),
        ("Object retrieved", "Detached and carried", f"{s['retrieved']}/{n}", f"{p('retrieved')}/{p('n_trials')}"),
        ("Spatial replication", "Placements with >= 1 retrieval", f"{s['placements_retrieved']}/{k}",
         f"{p('placements_retrieved')}/{p('n_placements')}"),
        ("Online correction", "State feedback during snap", s["online_correction"], p("online_correction")),
    ]
    return pd.DataFrame(rows, columns=["evidence", "criterion", "result", "paper"])


def markdown(df: pd.DataFrame) -> str:
    """results/tables/table2_deployment.md (pandas' writer; every cell as its text, no number parsing)."""
    return df.map(str).to_markdown(index=False, tablefmt="github", disable_numparse=True) + "\n"


def latex(df: pd.DataFrame) -> str:
    """results/tables/table2_deployment.tex: cells escaped for LaTeX, `>=` set as $\\geq$."""
    st = df.map(str).rename(columns=str.capitalize).style.hide(axis="index")
    st = st.format(lambda s: s.replace(">=", r"$\geq$"), escape="latex")
    return st.to_latex(column_format="@{}llll@{}", hrules=True)


def _ours(a, out) -> None:
    pl = a["manifest"]["placements"]
    d = [p["distance_m"] for p in pl]
    out["distance_range_m"] = [min(d), max(d)]
    b = np.asarray([p["bearing_deg"] for p in pl])
    out["bearing_range_deg"] = float(np.ptp(np.unwrap(np.deg2rad(b))) * 180 / np.pi)
    s = a["summary"]
    for k in s.keys():  # every summary number under its own name: the rows are the paper's claims
        out[k] = s[k]


def claims(s, man, path=None) -> list[dict]:
    """s: (summary path, summary); man: (manifest path, manifest); or the JSON alone."""
    return claim_rows("deployment", _ours, dict(summary=s, manifest=man), *([path] if path else []))

"""A number's lineage (issue 28): each claim names the artifact and key it was read from, as it is
computed; its recordings are the groups of the fit that wrote that artifact; `esnap audit CLAIM_ID`
and the ledger answer from the same code. Expected values are written out, never computed by the
code under test."""

from __future__ import annotations

import json

import pytest

from embodied_snap.lineage import numbers as N
from embodied_snap.lineage import records as pv
from embodied_snap.paper import ledger
from embodied_snap.sources import read_key, recordings, source_text, trace

from lineage_tree import group_files, write

# --- sources: read while the number is made ---------------------------------------------------------


def test_each_claim_names_the_leaves_it_read_and_only_those():
    servo = {"rate_tick_s": 3100.0, "ceiling_rad_s": [1.3, 2.1, 2.2], "n_bursts": 4}
    kin = {"lever_ticks_per_rad": [2300, 1450, 1440], "travel_per_tick_um": {"median": 15.8}}

    def ours(a, out):
        s, k = a["servo"], a["kin"]
        out["rate"] = s["rate_tick_s"]
        out["ceilings"] = s["ceiling_rad_s"]  # a list handed over whole: each element read
        out["ratio_s1"] = s["ceiling_rad_s"][0] * k["lever_ticks_per_rad"][0]  # two artifacts
        out["absent"] = k.get("no_such_key")

    values, src = trace(ours, dict(servo=("r/servo.json", servo), kin=("r/kin.json", kin)))
    assert values == {"rate": 3100.0, "ceilings": [1.3, 2.1, 2.2], "ratio_s1": 1.3 * 2300, "absent": None}
    assert src == {"rate": "r/servo.json:rate_tick_s",
                   "ceilings": "r/servo.json:ceiling_rad_s/*",
                   "ratio_s1": "r/kin.json:lever_ticks_per_rad/0 r/servo.json:ceiling_rad_s/0",
                   "absent": "r/kin.json:no_such_key"}


def test_keys_that_differ_in_one_place_merge_and_read_back():
    leaves = [("a.json", ("seeds", s, "at_s_mm", "0.3")) for s in ("0", "1", "2")] + [("a.json", ("n",))]
    assert source_text(leaves) == "a.json:n a.json:seeds/*/at_s_mm/0.3"
    assert source_text([("b.json", ("x", "0")), ("b.json", ("x", "1"))]) == "b.json:x/*"  # two are enough
    assert source_text([("b.json", ("x", "0")), ("b.json", ("y", "1"))]) == "b.json:x/0 b.json:y/1"
    doc = {"seeds": {"0": {"at_s_mm": {"0.3": 4.0}}, "1": {"at_s_mm": {"0.3": 5.0}}}, "l": [7, 8]}
    assert read_key(doc, "seeds/*/at_s_mm/0.3") == [4.0, 5.0] and read_key(doc, "l/1") == 8
    with pytest.raises(KeyError):
        read_key(doc, "seeds/9")


def test_a_fits_recordings_name_the_dropped_groups_with_the_rule():
    assert recordings(["g3", "g1", "g2"], ["g2", "g1"], "no finite peak tip speed") == {
        "used": ["g1", "g2"], "dropped": {"g3": "no finite peak tip speed"}}


def test_the_fits_that_drop_groups_record_them():
    """release, snap and the delay sweep leave a trial out by their own rule; the artifact says so."""
    import numpy as np

    from embodied_snap.characterize import delay, release

    rows = [dict(group_id=f"rel_{i}", category=c, v_peak=v, rate_peak=[1.0, 1.0, 1.0])
            for i, (c, v) in enumerate([("direct", 0.4), ("direct", np.nan), ("ramped", 1.2),
                                        ("instantaneous", 1.6)])]
    r = release.summarize(rows, [2.0, 2.0, 2.0], 1.0)["recordings"]
    assert r == {"used": ["rel_0", "rel_2", "rel_3"], "dropped": {"rel_1": "no finite peak tip speed"}}
    rows = [dict(group_id=f"dly_{i}", tau=t, v_peak=1.0 + i, attached=True, closest_m=0.01)
            for i, t in enumerate([0.3, None, 0.45])]
    assert delay.summarize(rows)["recordings"]["dropped"] == {"dly_1": "no S1 delay in its program"}


# --- the lineage of a number, on a small recorded tree -----------------------------------------------


def _tree(root, used=("cal_0001", "cal_0002", "cal_0003"), dropped=None):
    """Four calibration bursts and one attachment trial; the servo fit read the four bursts and
    records `used` of them; its claims job read the fit."""
    write(root, "raw_data/index.csv", ("group_id,evidence_set,category,session\n" + "".join(
        f"cal_000{i},servo_calibration,burst,s01\n" for i in range(1, 5)) + "att_0001,attachment,trial,s01\n").encode())
    files = [f for i in range(1, 5) for f in group_files(root, f"cal_000{i}")] + group_files(root, "att_0001")
    fit = dict(rate_tick_s=3100.0, recordings=dict(used=list(used), dropped=dropped or {"cal_0004": "too short"}))
    write(root, "results/characterize/servo.json", json.dumps(fit).encode())
    cal = [f for f in files if "/cal_" in f]
    pv.write_record("characterize_servo", {}, cal, ["results/characterize/servo.json"], {}, "t", root=root, reads=cal)
    write(root, "results/characterize/claims.csv", (
        "claim_id,section,quantity,paper,ours,unit,source\n"
        "servo_max_rate_tick_s,III-A,rate,3000,3100,tick/s,results/characterize/servo.json:rate_tick_s\n").encode())
    pv.write_record("table_characterize_claims", {}, ["results/characterize/servo.json"],
                    ["results/characterize/claims.csv"], {}, "t", root=root, reads=["results/characterize/servo.json"])
    return files


def test_a_claim_is_fed_by_exactly_the_groups_its_fit_used(tmp_path):
    _tree(tmp_path)
    lin = N.lineage("results/characterize/servo.json:rate_tick_s", tmp_path)
    assert N.fed_by(lin) == "servo_calibration 3/4"  # 4 read, the fit used 3; no attachment trial
    (a,) = lin["artifacts"]
    assert a["dropped"] == {"cal_0004": "too short"} and a["keys"] == ["rate_tick_s"]
    rows = ledger.ledger(["results/characterize/claims.csv"], tmp_path)
    assert rows[0]["fed_by"] == "servo_calibration 3/4"
    assert (rows[0]["source"], rows[0]["artifact"]) == ("results/characterize/servo.json:rate_tick_s",
                                                        "results/characterize/servo.json")


def test_a_fit_naming_a_group_its_jobs_never_read_is_refused(tmp_path):
    _tree(tmp_path, used=("cal_0001", "att_0001"))
    with pytest.raises(N.NumberError, match=r"^results/characterize/servo\.json: its recordings name group "
                                            r"att_0001, which its jobs never read"):
        N.lineage("results/characterize/servo.json:rate_tick_s", tmp_path)


def test_a_claim_with_no_source_or_one_its_job_did_not_read_is_refused(tmp_path):
    _tree(tmp_path)
    p = tmp_path / "results/characterize/claims.csv"
    for src, why in (("", "no source"), ("results/characterize/kinematics.json:x",
                                         "source results/characterize/kinematics.json is no input of its job")):
        p.write_text("claim_id,section,quantity,paper,ours,unit,source\nk,III-A,q,1,1,-," + src + "\n")
        with pytest.raises(ValueError, match=rf"claim k: {why}"):
            ledger.ledger(["results/characterize/claims.csv"], tmp_path)


def _ledger(root):
    rows = ledger.ledger(["results/characterize/claims.csv"], root)
    out = root / "results/tables"
    out.mkdir(parents=True, exist_ok=True)
    ledger.write(rows, out / "claims.csv", out / "claims.md", out / "claims.html")
    pv.write_record("table_claims", {}, ["results/characterize/claims.csv"], ["results/tables/claims.csv"], {}, "t",
                    root=root, reads=["results/characterize/claims.csv"])
    return rows


def test_audit_of_a_claim_and_of_file_key_and_the_stale_artifact(tmp_path):
    _tree(tmp_path)
    _ledger(tmp_path)
    r = N.audit_number("servo_max_rate_tick_s", tmp_path)
    assert r["stale"] == [] and r["ours"] == "3100"
    text = N.format_number(r)
    assert "read from results/characterize/servo.json" in text and "dropped by the fit: cal_0004 (too short)" in text
    assert "servo_calibration     3/4" in text
    r = N.audit_number("results/characterize/servo.json:rate_tick_s", tmp_path)
    assert r["ours"] == 3100.0 and r["claims"] == ["servo_max_rate_tick_s"]
    # the fit rerun after the ledger read it (its own record new, its lineage whole): stale all the same
    p = tmp_path / "results/characterize/servo.json"
    p.write_text(p.read_text().replace("3100.0", "3200.0"))
    cal = [f"raw_data/groups/cal_000{i}/{f}" for i in range(1, 5)
           for f in ("mocap.parquet", "servo.parquet", "meta.json")]
    pv.write_record("characterize_servo", {}, cal, ["results/characterize/servo.json"], {}, "t2", root=tmp_path,
                    reads=cal)
    r = N.audit_number("servo_max_rate_tick_s", tmp_path)
    assert r["stale"] == ["results/characterize/servo.json: changed after results/characterize/claims.csv was "
                          "written"]
    with pytest.raises(N.NumberError, match=r"^no_such_claim: no such claim in results/tables/claims\.csv"):
        N.audit_number("no_such_claim", tmp_path)
    with pytest.raises(N.NumberError, match=r"no key 'nope' in it"):
        N.audit_number("results/characterize/servo.json:nope", tmp_path)


def test_the_ledger_page_links_each_claim_to_its_audit(tmp_path):
    _tree(tmp_path)
    _ledger(tmp_path)
    page = (tmp_path / "results/tables/claims.html").read_text()
    assert '<a href="#audit-servo_max_rate_tick_s">servo_max_rate_tick_s</a>' in page
    assert '<section id="audit-servo_max_rate_tick_s">' in page and "servo_calibration     3/4" in page

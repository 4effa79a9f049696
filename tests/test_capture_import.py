"""`esnap import` (embodied_snap.capture.importer): a lab's exports of fakerig groups (tests/labexport.py)
imported back into the recording format, compared with the groups they came from, and every refusal
one stderr line naming the file, the take and the rule, with the raw directory left as it was.

Clocks. The exports count time from the native first frame t0 (capture = native t - t0). The servo
log is written with write_servo_log(offset_s=t0 + SYNC_S, drift_ppm=0): its t = native - t0 - SYNC_S,
so the lab's `sync: {event_time_s: SYNC_S}` (t_capture = t_servo + SYNC_S) puts it back on the
capture clock. fakerig's bodies do not follow its servos, so `sync: none` cannot align them.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from embodied_snap.capture.importer import SESSION_SCHEMA
from embodied_snap.cli import main
from embodied_snap.rawformat import BODIES, GOAL_TIMING, read_meta

from fakerig import write_fake_group, write_fake_raw
from labexport import (
    DEFAULT_NAMES,
    LAYOUT,
    SERVO_CLOCK_EVENTS,
    lab_doc,
    servo_clock,
    write_c3d,
    write_motive_csv,
    write_operator_labels,
    write_servo_log,
)

REPO = Path(__file__).resolve().parent.parent
SYNC_S = 0.25  # the servo log's t = 0 is the capture's 0.25 s
NOISE_M = 0.0003  # C3D marker noise per axis
IDS = ("dyn_0001", "dyn_0002")


def lab_file(path, fmt="csv", sync=None, bodies=BODIES):
    clock = dict(sync={"event_time_s": SYNC_S} if sync is None else sync, max_drift_ppm=100)
    lab = lab_doc("rigid_body" if fmt == "csv" else "markers", clock, bodies)
    path.write_text(yaml.safe_dump(lab, sort_keys=False))
    return path


def export(tmp, fmt="csv", ids=IDS, rate_hz=120, **kw):
    """Native fakerig groups under tmp/native, written out as one session under tmp/lab (Motive CSV in
    mm with occlusions, or C3D markers with 0.3 mm noise); returns (session file, lab file, native
    groups {id: (mocap, servo, meta)}, what each export wrote)."""
    native, out = tmp / "native", tmp / "lab"
    (out / "takes").mkdir(parents=True)
    groups, written, takes = {}, {}, []
    for i, gid in enumerate(ids):
        row = write_fake_group(native, gid, seed=i, **kw)
        d = native / "groups" / gid
        mocap, servo, meta = pd.read_parquet(d / "mocap.parquet"), pd.read_parquet(d / "servo.parquet"), read_meta(
            d / "meta.json")
        groups[gid] = (mocap, servo, meta)
        t0 = float(mocap.t.iloc[0])
        rng = np.random.default_rng(i)
        if fmt == "csv":
            written[gid] = write_motive_csv(mocap, out / f"takes/{gid}.csv", rate_hz=rate_hz, units="Millimeters",
                                            occlusions=2, rng=rng, gap_frames=(1, 3))
        else:
            written[gid] = write_c3d(mocap, out / f"takes/{gid}.c3d", {b: dict(LAYOUT) for b in BODIES},
                                     rate_hz=rate_hz, noise_m=NOISE_M, rng=rng)
        write_servo_log(servo, out / f"takes/{gid}_servo.csv", offset_s=t0 + SYNC_S, drift_ppm=0)
        events = {k: float(servo_clock(v, t0 + SYNC_S, 0)) for k, v in meta["labels"].items()
                  if k in SERVO_CLOCK_EVENTS}
        takes.append(dict(group_id=gid, evidence_set=row["evidence_set"], category=row["category"],
                          recorded_at=row["recorded_at"], mocap=f"takes/{gid}.{fmt}", servo=f"takes/{gid}_servo.csv",
                          program=meta["program"], events=events))
    write_operator_labels([g[2] for g in groups.values()], out / "labels.csv")
    session = out / "session.yaml"
    session.write_text(yaml.safe_dump(dict(session="s01", labels="labels.csv", takes=takes), sort_keys=False))
    return session, lab_file(out / "lab.yaml", fmt), groups, written


def esnap(capsys, monkeypatch, *argv):
    monkeypatch.chdir(REPO)  # config.yaml
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err.splitlines()


def run_import(capsys, monkeypatch, session, lab, raw):
    return esnap(capsys, monkeypatch, "import", session, "--lab", lab, "--raw", raw, "--quiet")


def digest(raw: Path):
    return {str(p.relative_to(raw)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(raw.rglob("*"))} if raw.exists() else None


def poses(df, body):
    p = df[[f"{body}_{a}" for a in "xyz"]].to_numpy(float)
    q = df[[f"{body}_{c}" for c in ("qw", "qx", "qy", "qz")]].to_numpy(float)
    return p, q, df[f"{body}_valid"].to_numpy(bool)


def pose_errors(raw, gid, mocap_native, written):
    """(position errors m, rotation errors rad) of the imported valid frames, all bodies,
    against the native poses at the exported frames; every imported frame is an exported one."""
    got = pd.read_parquet(raw / "groups" / gid / "mocap.parquet")
    t0 = float(mocap_native.t.iloc[0])
    k = np.rint(got.t.to_numpy() * written.rate_hz).astype(int)
    np.testing.assert_allclose(got.t.to_numpy(), written.t[k] - t0, atol=1e-6)
    native_at = mocap_native.set_index(np.round(mocap_native.t.to_numpy() - t0, 6))
    ref = native_at.loc[np.round(written.t[k] - t0, 6)]
    dp, dq = [], []
    for body in BODIES:
        p, q, v = poses(got, body)
        pn, qn, vn = poses(ref, body)
        assert v.any() and not (v & ~vn).any()  # no frame valid that the native did not track
        dp.append(np.linalg.norm(p[v] - pn[v], axis=1))
        # the rotation between them; the export's 6 decimals leave |q| 1e-6 off 1, too much for arccos
        dot = np.abs((q[v] * qn[v]).sum(1)) / np.linalg.norm(q[v], axis=1) / np.linalg.norm(qn[v], axis=1)
        dq.append(2 * np.arccos(np.clip(dot, 0, 1)))
    return np.concatenate(dp), np.concatenate(dq)


# --- the happy paths ----------------------------------------------------------------------------------


def test_motive_csv_imports_as_the_native_groups(tmp_path, capsys, monkeypatch):
    session, lab, groups, written = export(tmp_path)
    raw = tmp_path / "raw"
    rc, out, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 0, err
    index = pd.read_csv(raw / "index.csv")
    assert sorted(index.group_id) == list(IDS) and set(index.session) == {"s01"}
    for gid, (mocap, servo, meta) in groups.items():
        g = raw / "groups" / gid
        assert sorted(p.name for p in g.iterdir()) == ["meta.json", "mocap.parquet", "servo.parquet"]
        m = json.loads((g / "meta.json").read_text())
        assert m["clock"]["offset_s"] == SYNC_S and "sync event" in m["clock"]["method"]
        assert m["capture"]["rate_hz"] == 120 and m["capture"]["units"] == "Millimeters"
        assert m["labels"]["attached"] is meta["labels"]["attached"]
        # 6 decimals in mm: 5e-10 m; quaternion components: 5e-7
        dp, dq = pose_errors(raw, gid, mocap, written[gid])
        # 6 decimals in mm: 5e-10 m; 5e-7 per quaternion component, at most 2 |dq| = 2e-6 rad
        assert dp.max() < 1e-9 and dq.max() < 2e-6, (dp.max(), dq.max())
        # the occlusions the export added are gaps in the import
        assert not pd.read_parquet(g / "mocap.parquet")["tip_valid"].all()
        # the servo log's t is the native t on the capture clock (native - t0), to the log's microsecond
        got = pd.read_parquet(g / "servo.parquet")
        t = servo.t.to_numpy() - float(mocap.t.iloc[0])
        i = np.searchsorted(t, got.t.iloc[0] - 1e-6)
        np.testing.assert_allclose(got.t.to_numpy(), t[i:i + len(got)], atol=1e-6)
        np.testing.assert_array_equal(got.present_5.to_numpy(), servo.present_5.to_numpy()[i:i + len(got)])
    rc, out, err = esnap(capsys, monkeypatch, "validate", raw, "--source", "rig", "--partial")
    assert rc == 0, (out, err)


def test_c3d_markers_fit_the_native_poses(tmp_path, capsys, monkeypatch):
    session, lab, groups, written = export(tmp_path, fmt="c3d")
    raw = tmp_path / "raw"
    rc, out, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 0, err
    for gid, (mocap, _, _) in groups.items():
        dp, dq = pose_errors(raw, gid, mocap, written[gid])
        # 3 markers per body, 0.3 mm noise per axis: measured 0.32 mm 3D RMS (max 0.83 mm) and 1.05 deg
        # RMS (max 3.1 deg) on dyn_0001 and dyn_0002, over 3564 fitted frames each
        assert np.sqrt((dp**2).mean()) < 2 * NOISE_M and dp.max() < 5 * NOISE_M, dp
        assert np.degrees(np.sqrt((dq**2).mean())) < 2 and np.degrees(dq.max()) < 6, np.degrees(dq)


# --- refusals: one line naming the file, the take and the rule; the raw directory as it was --------------

BAD = "dyn_0002"  # the session's second take is the broken one: the first, good, must not land either


def rewrite_rows(path, edit):
    """edit(rows) on the CSV's rows (lists of cells) past Motive's 7 header rows."""
    lines = path.read_bytes().decode().split("\r\n")[:-1]
    rows = edit([ln.split(",") for ln in lines[7:]])
    path.write_bytes(("\r\n".join(lines[:7] + [",".join(r) for r in rows]) + "\r\n").encode())


def scale_base_quaternions(rows):
    for r in rows:
        r[2:6] = [c if c == "" else f"{0.9 * float(c):.6f}" for c in r[2:6]]
    return rows


def static_servo_log(tmp, groups):
    mocap, servo, _ = groups[BAD]
    servo = servo.copy()
    for c in servo.columns:
        if c.startswith(("goal_", "present_")):
            servo[c] = servo[c].iloc[0]
    write_servo_log(servo, tmp / "lab" / f"takes/{BAD}_servo.csv", offset_s=float(mocap.t.iloc[0]) + SYNC_S)
    lab_file(tmp / "lab" / "lab.yaml", sync="none")
    session = tmp / "lab" / "session.yaml"  # alone: on `sync: none` no fakerig take aligns
    doc = yaml.safe_load(session.read_text())
    doc["takes"] = doc["takes"][1:]
    session.write_text(yaml.safe_dump(doc, sort_keys=False))
    sheet(lambda s: "\n".join(ln for ln in s.splitlines() if not ln.startswith("dyn_0001")) + "\n")(tmp, groups)


def no_marker_labels(tmp, groups):
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [120]
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    c["parameters"]["POINT"]["LABELS"]["value"] = []
    c["data"]["points"] = np.ones((4, 0, 10))
    c.write(str(tmp / "lab" / f"takes/{BAD}.c3d"))
    session = tmp / "lab" / "session.yaml"
    doc = yaml.safe_load(session.read_text())
    doc["takes"][1]["mocap"] = f"takes/{BAD}.c3d"
    session.write_text(yaml.safe_dump(doc, sort_keys=False))


def sheet(edit):
    def f(tmp, groups):
        path = tmp / "lab" / "labels.csv"
        path.write_text(edit(path.read_text()))
    return f


def shift_servo(tmp, groups):
    path = tmp / "lab" / f"takes/{BAD}_servo.csv"
    log = pd.read_csv(path)
    log["t"] += 100
    log.to_csv(path, index=False, float_format="%.6f")


def text(edit):
    def f(tmp, groups):
        path = tmp / "lab" / f"takes/{BAD}.csv"
        path.write_bytes(edit(path.read_bytes().decode()).encode())  # Motive's CRLF kept
    return f


def rows(edit):
    return lambda tmp, groups: rewrite_rows(tmp / "lab" / f"takes/{BAD}.csv", edit)


def motive(**kw):
    return lambda tmp, groups: write_motive_csv(groups[BAD][0], tmp / "lab" / f"takes/{BAD}.csv", **kw)


CSV, SERVO, LABELS = f"takes/{BAD}.csv", f"takes/{BAD}_servo.csv", "labels.csv"
REFUSALS = {  # kind: (break it, the file at fault, the rule)
    "30-hz": (motive(rate_hz=30), CSV, "capture rate 100-500 Hz"),
    "missing-body": (motive(names={b: DEFAULT_NAMES[b] for b in BODIES if b != "s2"}), CSV,
                     "no rigid body 'S2' (the lab file's s2)"),
    "body-twice": (text(lambda s: s.replace(",S1,", ",S2,")), CSV, "Rigid Body 'S2' appears twice"),
    "no-units": (text(lambda s: s.replace(",Length Units,Millimeters", "")), CSV, "no Length Units"),
    "local-coordinates": (text(lambda s: s.replace("Coordinate Space,Global", "Coordinate Space,Local")), CSV,
                          "Coordinate Space 'Local'"),
    "time-off-the-frames": (rows(lambda r: r[:3] + [[r[3][0], f"{float(r[3][1]) + 0.001:.6f}", *r[3][2:]]] + r[4:]),
                            CSV, "frame 3: the Time column says"),
    "non-unit-quaternions": (rows(scale_base_quaternions), CSV, "unit base quaternions"),
    "frames-out-of-order": (rows(lambda r: r[:5] + [r[6], r[5]] + r[7:]), CSV, "frames out of order"),
    "frame-duplicated": (rows(lambda r: r[:6] + [r[5]] + r[6:]), CSV, "frame 5 is duplicated"),
    "no-marker-labels": (no_marker_labels, f"takes/{BAD}.c3d", "no point labels"),
    "truncated": (text(lambda s: s[: s.index("\r\n", len(s) // 2) - 7]), CSV, "truncated"),
    "servo-after-take": (shift_servo, SERVO, "the servo log overlaps the take"),
    "clock-not-found": (static_servo_log, SERVO, "flat correlation"),
    "attached-maybe": (sheet(lambda s: s.replace(f"{BAD},false", f"{BAD},maybe")), LABELS,
                       "attached is 'maybe' (rule: outcome labels are booleans)"),
    "foreign-row": (sheet(lambda s: s + "dyn_0099,false,false\n"), LABELS,
                    "take dyn_0099: not a take of this session"),
}


@pytest.mark.parametrize("kind", REFUSALS)
def test_a_bad_export_is_refused_and_nothing_written(tmp_path, capsys, monkeypatch, kind):
    session, lab, groups, _ = export(tmp_path)
    brk, culprit, rule = REFUSALS[kind]
    brk(tmp_path, groups)
    take = "" if kind == "foreign-row" else f"take {BAD}: "
    for raw in (tmp_path / "new", existing(tmp_path / "old")):
        before = digest(raw)
        rc, out, err = run_import(capsys, monkeypatch, session, lab, raw)
        assert rc == 1 and len(err) == 1, err
        assert f"{tmp_path / 'lab' / culprit}: {take}" in err[0] and rule in err[0], err
        assert digest(raw) == before
    assert not (tmp_path / "new").exists() and not list(tmp_path.glob(".esnap-import-*"))


def existing(raw):
    write_fake_raw(raw, ("dyn_0100",), duration_s=3.0)
    return raw


def test_a_group_already_there_is_never_overwritten(tmp_path, capsys, monkeypatch):
    session, lab, _, _ = export(tmp_path)
    raw = tmp_path / "raw"
    write_fake_raw(raw, (BAD,), duration_s=3.0)
    before = digest(raw)
    rc, out, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 1 and len(err) == 1 and f"{raw}: take {BAD}: already in {raw}" in err[0], err
    assert "an import never overwrites a group" in err[0]
    assert digest(raw) == before


def test_an_import_adds_to_the_index(tmp_path, capsys, monkeypatch):
    session, lab, _, _ = export(tmp_path)
    raw = existing(tmp_path / "raw")
    old = pd.read_csv(raw / "index.csv")
    rc, out, err = run_import(capsys, monkeypatch, session, lab, raw)
    assert rc == 0, err
    index = pd.read_csv(raw / "index.csv")
    assert sorted(index.group_id) == ["dyn_0001", "dyn_0002", "dyn_0100"]
    pd.testing.assert_frame_equal(index[index.group_id == "dyn_0100"].reset_index(drop=True), old)
    assert (raw / "groups" / "dyn_0100" / "meta.json").is_file()


@pytest.mark.parametrize("which", ["session", "lab"])
def test_a_missing_session_or_lab_file_is_a_usage_error(tmp_path, capsys, monkeypatch, which):
    session, lab, _, _ = export(tmp_path, ids=("dyn_0001",))
    (session if which == "session" else lab).unlink()
    rc, out, err = run_import(capsys, monkeypatch, session, lab, tmp_path / "raw")
    assert rc == 2 and len(err) == 1 and "no such file" in err[0], err
    assert str(session if which == "session" else lab) in err[0]
    assert not (tmp_path / "raw").exists()


def test_a_servo_log_esnap_deploy_wrote_carries_the_take_s_identity(tmp_path, capsys, monkeypatch):
    """servo: a group folder (servo.parquet + meta.json, as `esnap deploy --out` writes one): the
    group id, set, program and phase times come from its meta.json, the session names only mocap."""
    session, lab, groups, _ = export(tmp_path, ids=("dyn_0001",))
    mocap, servo, meta = groups["dyn_0001"]
    t0 = float(mocap.t.iloc[0])
    folder = tmp_path / "lab" / "deploy" / "groups" / "dep_0001"
    folder.mkdir(parents=True)
    log = servo.copy()
    log["t"] = servo_clock(log.t.to_numpy(), t0 + SYNC_S, 0)
    log.to_parquet(folder / "servo.parquet", index=False)
    phases = {k: float(servo_clock(v, t0 + SYNC_S, 0)) for k, v in meta["labels"].items() if k in SERVO_CLOCK_EVENTS}
    side = dict(format_version=1, group_id="dep_0001", evidence_set="deployment", category="placement",
                session="lab", recorded_at="2026-03-01T10:00:00", source="rig", program=meta["program"],
                labels=phases, manifest_sha256="ab" * 32, goal_timing="row")
    (folder / "meta.json").write_text(json.dumps(side))
    take = dict(mocap="takes/dyn_0001.csv", servo="deploy/groups/dep_0001")
    doc = dict(session="lab", labels="dep_labels.csv", takes=[take])
    (tmp_path / "lab" / "dep_labels.csv").write_text("group_id,attached,retrieved\ndep_0001,true,false\n")
    (tmp_path / "lab" / "dep.yaml").write_text(yaml.safe_dump(doc))
    raw = tmp_path / "raw"
    rc, out, err = run_import(capsys, monkeypatch, tmp_path / "lab" / "dep.yaml", lab, raw)
    assert rc == 0, err
    m = read_meta(raw / "groups" / "dep_0001" / "meta.json")
    assert (m["evidence_set"], m["program"], m["manifest_sha256"]) == ("deployment", meta["program"], "ab" * 32)
    assert m["goal_timing"] == "row"  # how the client logged its goals travels with the log
    assert m["labels"]["attached"] is True and m["labels"]["retrieved"] is False
    assert phases
    for k in phases:  # the servo PC's phase times, back on the capture clock
        assert m["labels"][k] == pytest.approx(meta["labels"][k] - t0, abs=1e-4)


def test_a_session_s_goal_timing_is_the_format_s():
    """A take's goal_timing (schemas/session.schema.yaml) allows exactly rawformat.GOAL_TIMING."""
    doc = yaml.safe_load(SESSION_SCHEMA.read_text())
    assert tuple(doc["$defs"]["take"]["properties"]["goal_timing"]["enum"]) == GOAL_TIMING


def test_every_capture_refusal_names_the_rule_it_breaks():
    """Each CaptureError in the readers is built as (file, what was found, rule), so the line a user
    reads ends with "(rule: ...)"; a call with the rule folded into its text, or without one, fails."""
    import ast

    import embodied_snap.capture as capture

    calls, bad = 0, []
    for f in sorted(Path(capture.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "CaptureError":
                calls += 1
                text = " ".join(ast.unparse(a) for a in node.args[:2])
                if len(node.args) != 3 or node.keywords or "rule:" in text:
                    bad.append(f"{f.name}:{node.lineno}")
    assert calls > 50 and not bad, bad

"""A corpus of broken (and a few benign) recordings, written against a finished smoke run of the
simulated rig (its ids: att_, cal_, rel_, dly_, dyn_, hb_; sealed dyn_0007/8). Independent of
fakerig and of tests/test_validate.py: each kind edits the raw tree the way a rig, an exporter
or a person could, and names what the gate must answer: (file, group, rule) of its one line, or
None for a benign kind that must pass.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

_OPENS: list[str] | None = None


def _audit(event, args):
    if event == "open" and _OPENS is not None and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENS.append(os.fsdecode(os.path.realpath(args[0])))  # realpath only lstats: opens nothing


@contextlib.contextmanager
def opens():
    """The real path of every file this process opens inside the block (Python's `open` audit
    event: every reader of the package goes through it, parquet included, embodied_snap/io.py)."""
    global _OPENS
    if not getattr(_audit, "installed", False):
        sys.addaudithook(_audit)  # once per process: an audit hook cannot be removed
        _audit.installed = True
    _OPENS = seen = []
    try:
        yield seen
    finally:
        _OPENS = None


def outside_targets(raw) -> list[str]:
    """Where each symlink under `raw` that leads outside it really points."""
    top = os.path.realpath(raw)
    out = []
    for d, dirs, files in os.walk(raw):
        for name in dirs + files:
            real = os.path.realpath(os.path.join(d, name))
            if os.path.islink(os.path.join(d, name)) and not real.startswith(top + os.sep):
                out.append(real)
    return out


def opened_any(seen, targets) -> list[str]:
    return [p for p in seen if any(p == t or p.startswith(t + os.sep) for t in targets)]


def _replace(path: Path, write) -> None:
    """Write beside and rename: the twin's recordings are read-only files."""
    fd, tmp = tempfile.mkstemp(dir=path.parent)
    os.close(fd)
    write(tmp)
    os.replace(tmp, path)


def _files(raw, gid):
    d = Path(raw) / "groups" / gid
    return d / "mocap.parquet", d / "servo.parquet", d / "meta.json"


def _index(raw) -> pd.DataFrame:
    return pd.read_csv(Path(raw) / "index.csv", dtype=str, keep_default_na=False)


def _write_index(raw, idx: pd.DataFrame) -> None:
    _replace(Path(raw) / "index.csv", lambda t: idx.to_csv(t, index=False))


def _sync(raw, gid):
    """Keep the index row counts in step, so only the intended rule breaks."""
    m, s, _ = _files(raw, gid)
    idx = _index(raw)
    i = idx.group_id == gid
    idx.loc[i, "n_mocap"] = str(len(pd.read_parquet(m)))
    idx.loc[i, "n_servo"] = str(len(pd.read_parquet(s)))
    _write_index(raw, idx)


def mocap(gid, fn):
    def apply(raw):
        p = _files(raw, gid)[0]
        df = fn(pd.read_parquet(p))
        _replace(p, lambda t: df.to_parquet(t, index=False))
        _sync(raw, gid)

    return apply


def servo(gid, fn):
    def apply(raw):
        p = _files(raw, gid)[1]
        df = fn(pd.read_parquet(p))
        _replace(p, lambda t: df.to_parquet(t, index=False))
        _sync(raw, gid)

    return apply


def meta(gid, fn):
    def apply(raw):
        p = _files(raw, gid)[2]
        m = json.loads(p.read_text())
        fn(m)
        _replace(p, lambda t: Path(t).write_text(json.dumps(m)))

    return apply


def index(fn):
    return lambda raw: _write_index(raw, fn(_index(raw)))


def raw_bytes(gid, which, data: bytes):
    def apply(raw):
        p = _files(raw, gid)["mocap servo meta".split().index(which)]
        _replace(p, lambda t: Path(t).write_bytes(data))

    return apply


def index_bytes(data: bytes):
    return lambda raw: _replace(Path(raw) / "index.csv", lambda t: Path(t).write_bytes(data))


def both(*fns):
    def apply(raw):
        for f in fns:
            f(raw)

    return apply


# --- edits ------------------------------------------------------------------------------------


def lose(body, start_s, length_s):
    """Tracking of `body` lost for length_s from start_s after the first sample (NaN pose)."""

    def fn(df):
        t = df.t - df.t.iloc[0]
        rows = (t >= start_s) & (t < start_s + length_s)
        df.loc[rows, f"{body}_valid"] = False
        cols = [f"{body}_{f}" for f in ("x", "y", "z", "qw", "qx", "qy", "qz")]
        df.loc[rows, cols] = np.nan
        return df

    return fn


def hole(start_s, length_s):
    """Rows missing altogether (the exporter skipped frames)."""
    return lambda df: df[
        ~((df.t - df.t.iloc[0] >= start_s) & (df.t - df.t.iloc[0] < start_s + length_s))
    ].reset_index(drop=True)


def jump(body, row, metres):
    def fn(df):
        df.loc[row, f"{body}_x"] += metres
        return df

    return fn


def swap(a, b, start, stop):
    """Two markers' labels swapped for a span of frames (a classic mocap relabel)."""

    def fn(df):
        rows = df.index[start:stop][(df[f"{a}_valid"] & df[f"{b}_valid"]).iloc[start:stop].to_numpy()]
        for f in ("x", "y", "z"):
            df.loc[rows, [f"{a}_{f}", f"{b}_{f}"]] = df.loc[rows, [f"{b}_{f}", f"{a}_{f}"]].to_numpy()
        return df

    return fn


def servo_gap(start_s, length_s):
    return lambda df: df[
        ~((df.t - df.t.iloc[0] >= start_s) & (df.t - df.t.iloc[0] < start_s + length_s))
    ].reset_index(drop=True)


def copy_group(src, dst):
    """A folder recorded but never listed in index.csv."""

    def apply(raw):
        import shutil

        shutil.copytree(Path(raw) / "groups" / src, Path(raw) / "groups" / dst)
        m = Path(raw) / "groups" / dst / "meta.json"
        m.chmod(0o644)
        mm = json.loads(m.read_text())
        mm["group_id"] = dst
        m.write_text(json.dumps(mm))

    return apply


def relabel_sealed(gid, cat):
    def apply(raw):
        index(lambda i: i.assign(category=np.where(i.group_id == gid, cat, i.category)))(raw)
        meta(gid, lambda m: m.update(category=cat))(raw)

    return apply


def symlinked_outside(gid):
    """The group's folder replaced by a symlink to a copy outside the raw directory."""

    def apply(raw):
        import shutil

        out = Path(raw).parent / f"outside_{gid}"
        shutil.copytree(Path(raw) / "groups" / gid, out)
        shutil.rmtree(Path(raw) / "groups" / gid)
        (Path(raw) / "groups" / gid).symlink_to(out.resolve())

    return apply


def linked_outside(gid, which):
    """One file of a group replaced by a symlink to a byte-identical copy outside the raw directory."""

    def apply(raw):
        import shutil

        p = _files(raw, gid)["mocap servo meta".split().index(which)]
        out = Path(raw).parent / f"outside_{gid}"
        out.mkdir()
        shutil.copy2(p, out / p.name)
        p.unlink()
        p.symlink_to((out / p.name).resolve())

    return apply


def linked_to(gid, which, target):
    """One file of a group replaced by a symlink to `target` (e.g. /etc/passwd)."""

    def apply(raw):
        p = _files(raw, gid)["mocap servo meta".split().index(which)]
        p.unlink()
        p.symlink_to(target)

    return apply


def groups_outside(raw):
    """groups/ itself moved outside the raw directory and linked back (every folder then leads out)."""
    import shutil

    out = Path(raw).parent / "outside_groups"
    shutil.copytree(Path(raw) / "groups", out, symlinks=True)
    shutil.rmtree(Path(raw) / "groups")
    (Path(raw) / "groups").symlink_to(out.resolve())


def linked_inside(gid, which):
    """One file moved to a store inside the raw directory and linked back: it stays inside."""

    def apply(raw):
        import shutil

        p = _files(raw, gid)["mocap servo meta".split().index(which)]
        store = Path(raw) / ".store"
        store.mkdir(exist_ok=True)
        shutil.move(p, store / f"{gid}_{p.name}")
        p.symlink_to(Path("..", "..", ".store", f"{gid}_{p.name}"))

    return apply


def copy_recordings(src, dst):
    """A take copied into another group: dst's mocap and servo logs replaced by copies of src's
    (`cp`), dst's meta.json and index row kept (row counts in step)."""

    def apply(raw):
        import shutil

        for a, b in zip(_files(raw, src)[:2], _files(raw, dst)[:2]):
            _replace(b, lambda t, a=a: shutil.copyfile(a, t))
        _sync(raw, dst)

    return apply


def link_recording(src, dst, which):
    """One of dst's logs replaced by a symlink to src's, inside the raw directory (a link allowed
    as such, as a deduplicated store's are)."""

    def apply(raw):
        p = _files(raw, dst)["mocap servo".split().index(which)]
        p.unlink()
        p.symlink_to(Path("..", src, p.name))
        _sync(raw, dst)

    return apply


def imported_twice(src, dst):
    """The same take imported again under a new id: a new group whose recordings are src's bytes
    and whose meta.json is src's under its own id, with its index row."""

    def apply(raw):
        copy_group(src, dst)(raw)
        add_row(dst, like=src)(raw)

    return apply


def add_row(gid, like="att_0001"):
    return index(lambda i: pd.concat([i, i[i.group_id == like].assign(group_id=gid)]))


def pop_label(gid, key):
    return meta(gid, lambda m: m["labels"].pop(key))


def set_label(gid, key, value):
    return meta(gid, lambda m: m["labels"].__setitem__(key, value))


def set_meta(gid, key, value):
    return meta(gid, lambda m: m.__setitem__(key, value))


def index_value(gid, col, value):
    return index(lambda i: i.assign(**{col: np.where(i.group_id == gid, value, i[col])}))


def hidden_things(raw):
    (Path(raw) / "groups" / ".DS_Store").write_bytes(b"\0\0\0\1Bud1")
    (Path(raw) / "groups" / ".cache").mkdir()


M, S, J, I = "mocap.parquet", "servo.parquet", "meta.json", "index.csv"

# kind -> (break it, (file the line names [group folder: ''], group, rule fragment) or None: passes)
CORPUS = {
    # mocap dropouts of various lengths, at the edges, bodies never tracked
    "tip dropout 0.15 s": (
        mocap("dyn_0001", lose("tip", 2.0, 0.15)),
        (M, "dyn_0001", "mocap dropout <= 0.1 s"),
    ),
    "tip dropout 0.5 s": (
        mocap("dyn_0003", lose("tip", 1.0, 0.5)),
        (M, "dyn_0003", "mocap dropout <= 0.1 s"),
    ),
    "s1 dropout 2 s": (mocap("att_0002", lose("s1", 1.0, 2.0)), (M, "att_0002", "mocap dropout <= 0.1 s")),
    "s2 dropout at the start": (
        mocap("rel_0002", lose("s2", 0.0, 0.3)),
        (M, "rel_0002", "mocap dropout <= 0.1 s"),
    ),
    "tip dropout at the end": (
        mocap("hb_0002", lose("tip", 1.6, 99.0)),
        (M, "hb_0002", "mocap dropout <= 0.1 s"),
    ),
    "base never tracked": (
        mocap("cal_0003", lose("base", 0.0, 99.0)),
        (M, "cal_0003", "mocap dropout <= 0.1 s"),
    ),
    "target never tracked": (
        mocap("att_0004", lose("target", 0.0, 99.0)),
        (M, "att_0004", "target tracked >= 50%"),
    ),
    "target mostly lost": (
        mocap("dly_0002", lose("target", 0.5, 99.0)),
        (M, "dly_0002", "target tracked >= 50%"),
    ),
    # holes in time (rows missing)
    "mocap hole 0.2 s": (mocap("dyn_0004", hole(1.0, 0.2)), (M, "dyn_0004", "mocap hole <= 0.1 s")),
    "mocap hole 1 s": (mocap("att_0005", hole(0.5, 1.0)), (M, "att_0005", "mocap hole <= 0.1 s")),
    # physically impossible motion
    "tip jumps 2 m for one frame": (
        mocap("dyn_0005", jump("tip", 700, 2.0)),
        (M, "dyn_0005", "tip speed <= 10 m/s"),
    ),
    "base jumps 5 cm for one frame": (
        mocap("hb_0003", jump("base", 300, 0.05)),
        (M, "hb_0003", "base speed <= 3 m/s"),
    ),
    "target jumps 1 m": (
        mocap("att_0006", jump("target", 400, 1.0)),
        (M, "att_0006", "target speed <= 5 m/s"),
    ),
    "s1 and s2 markers swapped": (
        mocap("rel_0004", swap("s1", "s2", 400, 460)),
        (M, "rel_0004", "s1 speed <= 6 m/s"),
    ),
    # format and units
    "positions in millimetres": (
        mocap("dyn_0009", lambda d: d.assign(**{c: d[c] * 1000 for c in d if c[-2:] in ("_x", "_y", "_z")})),
        (M, "dyn_0009", "bodies within 2 m of the base"),
    ),
    "NaN pose in a valid sample": (
        mocap("cal_0004", lambda d: d.assign(tip_y=np.where(d.index == 50, np.nan, d.tip_y))),
        (M, "cal_0004", "valid tip samples complete"),
    ),
    "time goes backwards": (
        mocap("dly_0003", lambda d: d.assign(t=np.where(d.index == 100, d.t - 0.5, d.t))),
        (M, "dly_0003", "t strictly increasing"),
    ),
    "mocap truncated": (
        lambda raw: raw_bytes("rel_0005", "mocap", _files(raw, "rel_0005")[0].read_bytes()[:5000])(raw),
        (M, "rel_0005", "readable parquet"),
    ),
    "mocap empty file": (raw_bytes("dyn_0010", "mocap", b""), (M, "dyn_0010", "readable parquet")),
    # servo log
    "servo dropout 0.5 s (dynamics)": (
        servo("dyn_0002", servo_gap(2.0, 0.5)),
        (S, "dyn_0002", "servo log gap <= 0.05 s"),
    ),
    "servo dropout 2 s": (servo("dyn_0011", servo_gap(1.0, 2.0)), (S, "dyn_0011", "servo log gap <= 0.05 s")),
    "servo dropout 0.1 s (calibration)": (
        servo("cal_0005", servo_gap(0.6, 0.1)),
        (S, "cal_0005", "servo log gap <= 0.05 s"),
    ),
    "servo log ends early": (
        servo("att_0007", lambda d: d[d.t < d.t.max() - 1.0]),
        (S, "att_0007", "servo log covers mocap"),
    ),
    "servo ticks as floats": (
        servo("hb_0004", lambda d: d.assign(goal_3=d.goal_3 + 0.5)),
        (S, "hb_0004", "ticks are integers"),
    ),
    "servo empty file": (raw_bytes("dly_0004", "servo", b""), (S, "dly_0004", "readable parquet")),
    # meta.json: version, labels, program, target
    "format_version 2": (set_meta("dyn_0012", "format_version", 2), (J, "dyn_0012", "format version 1")),
    "format_version as text": (
        set_meta("att_0008", "format_version", "1"),
        (J, "att_0008", "format version 1"),
    ),
    "goal_timing unknown": (
        set_meta("cal_0003", "goal_timing", "later"),
        (J, "cal_0003", "goal_timing one of interval, row"),
    ),
    "labels missing": (
        meta("rel_0006", lambda m: m.pop("labels")),
        (J, "rel_0006", "labels complete per evidence set"),
    ),
    "t_s1 missing (delay sweep)": (
        pop_label("dly_0005", "t_s1"),
        (J, "dly_0005", "labels complete per evidence set"),
    ),
    "attached missing (attachment)": (
        pop_label("att_0003", "attached"),
        (J, "att_0003", "labels complete per evidence set"),
    ),
    "t_up missing (calibration)": (
        pop_label("cal_0006", "t_up"),
        (J, "cal_0006", "labels complete per evidence set"),
    ),
    "label time after the recording": (
        set_label("dyn_0013", "t_s2", 99.0),
        (J, "dyn_0013", "label times inside the recording"),
    ),
    "attached as text": (
        set_label("dly_0006", "attached", "yes"),
        (J, "dly_0006", "outcome labels are booleans"),
    ),
    "program without tau": (
        meta("dyn_0014", lambda m: m["program"].pop("tau")),
        (J, "dyn_0014", "program complete per evidence set"),
    ),
    "target trial without target": (
        meta("att_0001", lambda m: m.pop("target")),
        (J, "att_0001", "target trials describe the target"),
    ),
    "meta.json empty": (raw_bytes("rel_0007", "meta", b""), (J, "rel_0007", "meta.json is JSON")),
    "meta.json disagrees with index": (
        set_meta("rel_0008", "category", "ramped"),
        (J, "rel_0008", "meta.json agrees with index.csv"),
    ),
    # index.csv and ids
    "index.csv empty": (index_bytes(b""), (I, "-", "index.csv has a header")),
    "index.csv not text": (index_bytes(bytes(range(256)) * 4), (I, "-", "readable csv")),
    "index.csv without n_servo": (index(lambda i: i.drop(columns="n_servo")), (I, "-", "required columns")),
    "group id ../../x": (add_row("../../x"), (I, "../../x", "group id pattern")),
    "group id /etc": (add_row("/etc"), (I, "/etc", "group id pattern")),
    "duplicate group id": (index(lambda i: pd.concat([i, i.iloc[[3]]])), (I, "att_0004", "unique group_id")),
    "unknown evidence set": (
        index_value("cal_0007", "evidence_set", "calibration"),
        (I, "cal_0007", "known evidence set"),
    ),
    "unknown category": (index_value("rel_0003", "category", "snap"), (I, "rel_0003", "known category")),
    "folder without index row": (
        copy_group("att_0001", "att_0099"),
        ("", "att_0099", "every group has an index row"),
    ),
    "index row without files": (add_row("att_0098"), (J, "att_0098", "group has its three files")),
    "n_mocap mismatch": (
        index_value("cal_0008", "n_mocap", "7"),
        (I, "cal_0008", "n_mocap matches mocap.parquet"),
    ),
    "group folder symlinked outside": (
        symlinked_outside("hb_0001"),
        ("", "hb_0001", "group folder inside the raw directory"),
    ),
    # the raw directory is closed: a link out is refused before its target is opened
    "mocap linked to a copy outside": (
        linked_outside("att_0003", "mocap"),
        (M, "att_0003", "file inside the raw directory"),
    ),
    "meta.json linked to /etc/passwd": (
        linked_to("rel_0001", "meta", "/etc/passwd"),
        (J, "rel_0001", "file inside the raw directory"),
    ),
    "groups/ linked outside": (groups_outside, ("", "att_0001", "group folder inside the raw directory")),
    # one recording, one group: the same file or the same bytes under two labels
    "take copied into another group": (
        copy_recordings("att_0002", "att_0005"),
        (M, "att_0005", "one recording, one group"),
    ),
    "take linked from another group": (
        link_recording("cal_0002", "cal_0006", "mocap"),
        (M, "cal_0006", "one recording, one group"),
    ),
    "same take imported twice": (
        imported_twice("rel_0003", "rel_0097"),
        (M, "rel_0097", "one recording, one group"),
    ),
    # the sealed set
    "sealed group relabelled free_space": (
        relabel_sealed("dyn_0007", "free_space"),
        ("sealed.json", "dyn_0007", "sealed set is fixed"),
    ),
    "sealed group re-recorded": (
        mocap("dyn_0008", jump("tip", 10, 1e-4)),
        (M, "dyn_0008", "sealed set is fixed"),
    ),
    # benign: the gate lets these through
    "tip dropout 0.05 s": (mocap("dyn_0001", lose("tip", 2.0, 0.05)), None),
    "servo gap 0.03 s": (servo("dyn_0002", servo_gap(2.0, 0.03)), None),
    "target lost 0.3 s in a target trial": (mocap("att_0002", lose("target", 1.0, 0.3)), None),
    "meta.json without format_version": (meta("att_0003", lambda m: m.pop("format_version")), None),
    "meta.json with an operator note": (set_meta("cal_0001", "note", "cable re-tensioned"), None),
    "extra label": (set_label("dyn_0003", "operator_ok", True), None),
    "index.csv rows shuffled": (index(lambda i: i.sample(frac=1, random_state=1)), None),
    "hidden files in groups/": (hidden_things, None),
    "servo.parquet linked inside the raw directory": (linked_inside("dyn_0004", "servo"), None),
}
BENIGN = [k for k, (_, want) in CORPUS.items() if want is None]

# With the simulated rig (raw_data.source twin) the plan comes from the budget, and index.csv must
# agree with it: these kinds break that rule first. Every other kind gets the same line either way.
TWIN = {
    "index row without files": (I, "att_0098", "index.csv matches the simulated rig's plan"),
    "sealed group relabelled free_space": (I, "dyn_0007", "index.csv matches the simulated rig's plan"),
    "same take imported twice": (I, "rel_0097", "index.csv matches the simulated rig's plan"),
}

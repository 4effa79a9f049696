"""`esnap deploy` refuses every argument that could move the arm differently from what was asked,
in one line, before any port opens (embodied_snap/deploy/arguments.py; docs/deployment.md,
"Arguments that could move the arm differently"). Each invocation names a port and --yes, so a
refusal that came too late would open it: the port opener fails the test when it is called."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import test_deploy

from embodied_snap.cli import main
from embodied_snap.deploy import arguments as A
from embodied_snap.deploy import client
from embodied_snap.deploy import manifest as MF

_man = test_deploy._man
man_path = test_deploy.man_path  # the deployment tests' manifest fixture, reused


pytestmark = pytest.mark.usefixtures("no_port")  # conftest: opening a port fails the test


def deploy(capsys, man_path, *args, port=True):
    argv = ["deploy", "--manifest", str(man_path), *(["--port", "/dev/ttyUSB9", "--yes"] if port else []), *args]
    rc = main(argv)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].strip() and "Traceback" not in err[0], err
    return rc, err[0]


def _tampered(man_path, tmp_path, **servos) -> Path:
    """The manifest with other servo settings, its checksum recomputed (as a re-export would)."""
    man = _man(man_path)
    man["servos"].update(servos)
    man["checksum"] = MF.checksum(man)
    p = tmp_path / "manifest.json"
    p.write_text(json.dumps(man))
    return p


@pytest.mark.parametrize("k", ["0", "-1", "4", "99"])
def test_placement_outside_1_to_n(capsys, man_path, k):
    """--placement 0 planned the last placement (placements[k - 1]); 99 was an IndexError."""
    rc, err = deploy(capsys, man_path, "--placement", k)
    assert rc == 2 and f"--placement {k}: the manifest has placements 1..3" in err


@pytest.mark.parametrize("xyz", ["1,2", "1,2,3,4", "a,b,c", "nan,-0.5,0.2", "0.1,inf,0.2", "1e999,0,0", ""])
def test_target_not_three_finite_numbers(capsys, man_path, xyz):
    rc, err = deploy(capsys, man_path, f"--target={xyz}")
    assert rc == 2 and "expected three finite numbers" in err


@pytest.mark.parametrize("xyz", ["0,-0.1,0", "120,-450,-600"])  # beside the base; millimetres for metres
def test_target_outside_the_workspace(capsys, man_path, xyz):
    rc, err = deploy(capsys, man_path, f"--target={xyz}")
    assert rc == 1 and err.startswith("error: refused: target") and "outside the workspace" in err


@pytest.mark.parametrize("content, says", [
    (None, "cannot read it"),
    ("{not json", "not JSON"),
    ("[0.1, -0.5, 0.2]", "expected exactly"),
    ('{"target": [0.1, -0.5, 0.2]}', "expected exactly"),
    ('{"target_m": [0.1, -0.5, 0.2], "frame": "world"}', "expected exactly"),  # another frame
    ('{"target_m": [0.1, -0.5]}', "expected three finite numbers"),
    ('{"target_m": ["0.1", "-0.5", "0.2"]}', "expected three finite numbers"),
    ('{"target_m": [true, -0.5, 0.2]}', "expected three finite numbers"),
    ('{"target_m": [NaN, -0.5, 0.2]}', "expected three finite numbers"),
])
def test_mocap_file_not_exactly_one_target(capsys, man_path, tmp_path, content, says):
    p = tmp_path / "block.json"
    if content is not None:
        p.write_text(content)
    rc, err = deploy(capsys, man_path, "--target-from-mocap", str(p))
    assert rc == 2 and err.startswith(f"esnap deploy: error: --target-from-mocap {p}") and says in err


@pytest.mark.parametrize("baud, says", [("19200", "not a baud rate of the XM430"), ("0", "not a baud rate"),
                                        ("4500000", "dynamixel-sdk cannot set it")])
def test_baud_the_servos_do_not_run_at(capsys, man_path, baud, says):
    rc, err = deploy(capsys, man_path, "--placement", "1", "--baud", baud)
    assert rc == 2 and f"--baud {baud}: " in err and says in err


def test_manifest_baud_the_servos_do_not_run_at(capsys, man_path, tmp_path):
    rc, err = deploy(capsys, _tampered(man_path, tmp_path, baud=38400), "--placement", "1")
    assert rc == 2 and "the manifest's servos.baud 38400: not a baud rate of the XM430" in err


@pytest.mark.parametrize("ids", [[1, 1, 3, 4, 5, 6, 7, 8, 9], list(range(0, 9)), list(range(1, 9))])
def test_servo_ids_not_1_to_9_once(capsys, man_path, tmp_path, ids):
    rc, err = deploy(capsys, _tampered(man_path, tmp_path, ids=ids), "--placement", "1")
    assert rc == 2 and "servos.ids" in err and "expected 1..9, each once" in err


@pytest.mark.parametrize("gid", ["../dep_0001", "a/b", ""])
def test_group_id_that_is_a_path(capsys, man_path, gid):
    rc, err = deploy(capsys, man_path, "--placement", "1", "--group-id", gid)
    assert rc == 2 and "--group-id" in err


def test_out_that_cannot_be_written(capsys, man_path, tmp_path):
    (tmp_path / "afile").write_text("")
    rc, err = deploy(capsys, man_path, "--placement", "1", "--out", str(tmp_path / "afile" / "tree"))
    assert rc == 2 and "--out" in err and "cannot write there" in err


def test_no_port_no_terminal_no_target(capsys, man_path):
    rc, err = deploy(capsys, man_path, "--placement", "1", port=False)
    assert rc == 2 and "--port is required" in err
    rc, err = deploy(capsys, man_path, "--placement", "1", "--port", "/dev/ttyUSB9", port=False)
    assert rc == 2 and "--yes is required when stdin is not a terminal" in err  # pytest's stdin is none
    rc, err = deploy(capsys, man_path)
    assert rc == 2 and "give --target, --target-from-mocap or --placement" in err


def test_placement_k_plans_placement_k(man_path):
    """What is accepted is what the trial uses: placement k's own target, the manifest's baud."""
    man = _man(man_path)
    for k in (1, 2, 3):
        a = type("Args", (), dict(placement=k, target=None, target_from_mocap=None, baud=None,
                                  group_id="dep_0001", out=None))
        got = A.check(man, a)
        assert got["target"] == man["placements"][k - 1]["target_m"] and got["baud"] == man["servos"]["baud"]
    with pytest.raises(A.ArgumentError):
        A.placement(man, 0)


def test_a_nan_target_is_outside_the_workspace(man_path):
    """commands.commands read `np.any(g < lo)`, False for NaN: a NaN feature passed the box."""
    with pytest.raises(client.C.RefusedTarget):
        client.C.commands(_man(man_path), [float("nan"), -0.5, 0.2])


@pytest.mark.parametrize("kw, rule", [(dict(placement=0), "placements 1..3"), (dict(baud=12345), "not a baud rate"),
                                      (dict(placement=4), "placements 1..3")])
def test_the_client_itself_refuses_before_the_port(man_path, kw, rule):
    """client.run is the one door to the port (esnap deploy and the simulated rig's trials): it
    checks placement and baud again, whoever calls it."""
    target = _man(man_path)["placements"][0]["target_m"]
    with pytest.raises(client.DeployError, match=rule):
        client.run(man_path, "/dev/ttyUSB9", target, say=lambda *_: None, **kw)


OPENED: list[str] | None = None


def _watch_opens(event, args):
    if event == "open" and OPENED is not None:
        OPENED.append(str(args[0]))


def test_a_lab_trial_linked_out_of_its_tree_is_listed_unread(tmp_path):
    """`esnap deploy-index`: a trial whose meta.json is a link out of the deployment tree is listed
    with the gate's rule as its cause, and the file it points at is never opened."""
    import sys

    from embodied_snap.deploy import trials as T

    global OPENED
    secret = tmp_path / "secret.json"
    secret.write_text("{}")
    (tmp_path / "dep/groups/dep_0001").mkdir(parents=True)
    (tmp_path / "dep/groups/dep_0001/meta.json").symlink_to(secret)
    sys.addaudithook(_watch_opens)  # hooks cannot be removed: it records only while OPENED is a list
    OPENED = []
    try:
        found = T.lab_trials(tmp_path / "dep")
    finally:
        seen, OPENED = OPENED, None
    assert [r["group_id"] for r in found] == ["dep_0001"] and "outside" in found[0]["cause"], found
    assert str(secret) not in seen

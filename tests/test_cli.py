"""Every `esnap` subcommand answers a bad invocation in one line on stderr: exit status 2 for a
usage error, 1 for a check that failed, never a traceback and never the catch-all "internal
error" (that line means a case no command handles). The bad invocations are generated from the
argparse parser itself, so a new subcommand or option is tested without an edit here; the cases
the issue named are listed below them. In-process, in an empty directory holding only config.yaml.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import test_deploy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

from embodied_snap import cli

man_path = test_deploy.man_path  # the deployment tests' manifest fixture, reused

ROOT = Path(__file__).resolve().parent.parent
UNDER_A_FILE = "afile/x"  # a path nothing can be read from or written to (not even by root)
HOSTILE = ["", UNDER_A_FILE, UNDER_A_FILE + "/"]
# Nothing of hypothesis's left in the checkout (no example database, its caches under the temp dir);
# the fixture's directory is the same for every example, and each example leaves nothing in it.
set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "esnap-hypothesis")
# ESNAP_CLI_EXAMPLES=2000 explores further (about 30 s); 150 keeps the file under 15 s
SETTINGS = settings(max_examples=int(os.environ.get("ESNAP_CLI_EXAMPLES", 150)), deadline=None, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture
def cwd(tmp_path, monkeypatch):
    shutil.copy(ROOT / "config.yaml", tmp_path / "config.yaml")
    (tmp_path / "afile").write_text("")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def esnap(capsys, argv) -> tuple[int, list[str]]:
    rc = cli.main(list(argv))
    return rc, capsys.readouterr().err.splitlines()


def assert_one_line(argv, rc, err) -> None:
    assert rc in (1, 2), (argv, rc, err)
    assert len(err) == 1 and err[0].strip(), (argv, err)
    assert "Traceback" not in err[0] and "internal error" not in err[0], (argv, err)


# --- the parser, walked -------------------------------------------------------------------------------

def subcommands(parser=None, prefix="") -> dict[str, argparse.ArgumentParser]:
    """Every (sub)command that takes arguments, nested ones by their words ("lab acquire")."""
    out = {}
    sp = next(a for a in (parser or cli.parser())._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in sp.choices.items():
        nested = any(isinstance(a, argparse._SubParsersAction) for a in sub._actions)
        out.update(subcommands(sub, f"{prefix}{name} ") if nested else {f"{prefix}{name}": sub})
    return out


SUBS = subcommands()
SKIP = (argparse._HelpAction, argparse._VersionAction)


def _options(sub):
    return [a for a in sub._actions if a.option_strings and not isinstance(a, SKIP)]


def _flags(sub):
    return [a.option_strings[-1] for a in _options(sub) if a.nargs == 0]


def _valued(sub):
    return [a for a in _options(sub) if a.nargs != 0]


def _typed(a) -> bool:
    return a.type is not None and a.type is not str


def parse_errors(sub) -> list[list[str]]:
    """Argument lists argparse itself must refuse, from what the subparser declares."""
    bad = [["--no-such-option"], ["stray", "positionals", "beyond", "any", "it", "takes"]]
    for a in _valued(sub):
        opt = a.option_strings[-1]
        bad.append([opt])  # no value (placed last)
        if _typed(a):
            bad += [[opt, "x"], [opt, "1.5"]]
        if a.choices:
            bad.append([opt, "no-such-choice"])
    for a in sub._actions:
        if not a.option_strings and a.choices:
            bad.append(["no-such-choice"])
    return bad


def hostile(sub) -> list[tuple[str | None, str]]:
    """(option or None for a positional, its value) for every free-text argument: a hostile value is
    a path that is empty or lies under a regular file, which no command may take."""
    out = [(a.option_strings[-1], v) for a in _valued(sub) if not _typed(a) and not a.choices for v in HOSTILE]
    for a in sub._actions:
        if not a.option_strings and not a.choices and not isinstance(a, SKIP):
            out += [(None, v) for v in HOSTILE]
    return out


@st.composite
def bad_argv(draw):
    name = draw(st.sampled_from(sorted(SUBS)))
    sub = SUBS[name]
    flags = draw(st.lists(st.sampled_from(_flags(sub)), unique=True)) if _flags(sub) else []
    return [*name.split(), *flags, *draw(st.sampled_from(parse_errors(sub)))]


@st.composite
def hostile_argv(draw):
    name = draw(st.sampled_from([n for n in sorted(SUBS) if hostile(SUBS[n])]))
    sub = SUBS[name]
    flags = draw(st.lists(st.sampled_from(_flags(sub)), unique=True)) if _flags(sub) else []
    picked = draw(st.lists(st.sampled_from(hostile(sub)), min_size=1, max_size=3, unique_by=lambda x: x[0]))
    pos = [v for opt, v in picked if opt is None]
    return [*name.split(), *pos, *flags, *[x for opt, v in picked if opt for x in (opt, v)]]


def test_every_subcommand_is_generated():
    assert {"twin", "validate", "seal", "audit", "check-separation", "deploy", "claims", "lab plan",
            "lab acquire"} <= set(SUBS)
    assert all(parse_errors(s) for s in SUBS.values())


@SETTINGS
@given(argv=bad_argv())
def test_parse_errors_are_one_line(cwd, capsys, argv):
    rc, err = esnap(capsys, argv)
    assert_one_line(argv, rc, err)
    assert rc == 2 and "error:" in err[0]


@SETTINGS
@given(argv=hostile_argv())
def test_hostile_values_are_one_line(cwd, capsys, argv):
    rc, err = esnap(capsys, argv)
    assert_one_line(argv, rc, err)


# --- the cases issue 24 named -----------------------------------------------------------------------

KNOWN = [
    (["validate", "--configfile", "bad.yaml"], 2, "config: gate.max_servo_gap_s: 'fast' is not of type 'number'"),
    (["validate", "--configfile", "missing.yaml"], 2, "--configfile missing.yaml: no such file"),
    (["validate", "--config", "budget=nonsense"], 2, "config: budget: 'nonsense' is not one of"),
    (["validate", "--config", "budgte=smoke"], 2, "config: Additional properties are not allowed ('budgte'"),
    (["validate", "--config", "budget"], 2, "--config: expected at least one argument"),
    (["validate", "--budget", "smoke"], 2, "unrecognized arguments: --budget"),  # the old flag is gone
    (["validate"], 2, "recording tree raw_data: no such directory"),
    (["twin", "acquire", "--jobs", "0"], 2, "argument --jobs: 0: expected 1 or more"),
    (["twin", "acquire", "--evidence-set", "nope"], 2, "--evidence-set nope: not in the plan"),
    (["twin", "phenomena"], 2, "--raw-dir raw_data: no such directory"),
    (["twin", "phenomena", "--raw-dir", "empty"], 1, "missing (record the groups first: esnap twin acquire)"),
    (["crate", "--verify"], 1, "no crate"),
    (["report-check", "/nonexistent.html"], 2, "report /nonexistent.html: no such file"),
    (["audit", "results/figures/nope.pdf"], 2, "results/figures/nope.pdf: no such file or directory"),
    (["audit", "--config", "budget=nonsense", "results/x.txt"], 2, "config: budget: 'nonsense' is not one of"),
    (["check-separation", "--config", "budget=nonsense"], 2, "config: budget: 'nonsense' is not one of"),
    (["check-separation", "--root", "nowhere"], 2, "--root nowhere: no such directory"),
    (["deploy-index", "--planned", "-1"], 2, "argument --planned: -1: expected 1 or more"),
    (["claims"], 1, "no claims ledger"),
    (["claims", "--ledger", "bad.csv"], 1, "not a claims ledger"),
    (["prov", "--out", "afile/prov.json"], 2, "--out afile/prov.json: cannot write it"),
    (["resources"], 2, "--benchmarks benchmarks: no such directory"),
    (["deploy", "--placement", "1", "--dry-run"], 2, "--manifest results/deployment/manifest.json: no such file"),
    (["deploy", "--manifest", "{man}", "--placement", "99", "--dry-run"], 2, "--placement 99: the manifest has"),
    (["deploy", "--manifest", "{man}", "--placement", "0", "--dry-run"], 2, "--placement 0: the manifest has"),
    (["deploy", "--manifest", "{man}", "--target", "1,2", "--dry-run"], 2, "--target 1,2: expected three finite"),
    (["nope"], 2, "invalid choice: 'nope'"),
    ([], 2, "the following arguments are required: COMMAND"),
]


@pytest.mark.parametrize("argv, code, says", KNOWN, ids=[" ".join(k[0]) or "(none)" for k in KNOWN])
def test_known_bad_invocations(cwd, capsys, man_path, argv, code, says):
    (cwd / "bad.yaml").write_text("gate:\n  max_servo_gap_s: fast\n")  # a gate limit as text
    (cwd / "bad.csv").write_text("a,b\n1,2\n")
    (cwd / "results").mkdir()
    (cwd / "results/x.txt").write_text("")
    (cwd / "empty").mkdir()
    argv = [x.format(man=man_path) for x in argv]
    rc, err = esnap(capsys, argv)
    assert_one_line(argv, rc, err)
    assert rc == code and says in err[0], err


def test_config_does_not_swallow_the_positional(cwd):
    """Snakemake's --config takes every KEY=VALUE after it; a positional after them is still one."""
    a = cli.parser().parse_args(cli._config_last(["audit", "--config", "budget=smoke", "seed=3", "results/x.txt"]))
    assert a.result == "results/x.txt" and a.config == ["budget=smoke", "seed=3"]
    a = cli.parser().parse_args(cli._config_last(["validate", "--config", "budget=smoke", "--", "raw"]))
    assert a.raw_dir == "raw" and a.config == ["budget=smoke"]


def test_config_is_snakemakes(cwd):
    """The same config a snakemake run with these arguments validates: config.yaml, the file, the
    overrides, merged as Snakemake merges them; the schema fills nothing in (it has no defaults)."""
    from embodied_snap import runconfig

    (cwd / "more.yaml").write_text("resample: {max_gap_s: 0.2}\n")
    cfg = runconfig.load("more.yaml", ["budget=smoke", "raw_data={source: rig}"])
    assert cfg["budget"] == "smoke" and cfg["resample"]["max_gap_s"] == 0.2 and cfg["raw_data"]["source"] == "rig"
    assert cfg["raw_data"]["dir"] == "raw_data"  # config.yaml's, kept: an override updates a section
    (cwd / "config.yaml").unlink()  # no workflow config: the file alone, and it lacks keys
    with pytest.raises(runconfig.ConfigError) as e:
        runconfig.load("more.yaml", ["budget=smoke"])
    says = str(e.value)
    assert says.startswith("config: ") and says.endswith("is a required property") and "\n" not in says, says


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.startswith("esnap ")


def test_ctrl_c_and_a_closed_pipe(cwd, capsys, monkeypatch):
    from embodied_snap.paper import ledger

    (cwd / "results/tables").mkdir(parents=True)
    (cwd / "results/tables/claims.csv").write_text(",".join(ledger.COLUMNS) + "\n")

    def interrupted(path):
        raise KeyboardInterrupt

    monkeypatch.setattr(ledger, "read", interrupted)
    rc, err = esnap(capsys, ["claims"])
    assert rc == 130 and err == ["esnap claims: interrupted"]
    monkeypatch.undo()
    monkeypatch.chdir(cwd)

    class Closed:
        def write(self, s):
            raise BrokenPipeError

        def flush(self):
            raise BrokenPipeError

    monkeypatch.setattr(sys, "stdout", Closed())
    rc = cli.main(["claims"])
    monkeypatch.undo()
    assert rc == 141 and capsys.readouterr().err == ""


def test_claims_into_head_is_quiet(tmp_path):
    """`esnap claims | head -1`: the reader goes away; no traceback, no 'Exception ignored'."""
    from embodied_snap.paper import ledger

    with open(tmp_path / "claims.csv", "w", newline="") as f:
        w = csv.DictWriter(f, ledger.COLUMNS)
        w.writeheader()
        for k in range(20000):
            w.writerow(dict.fromkeys(ledger.COLUMNS, "x") | dict(claim_id=f"c{k}", status="agrees", explained_in=""))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run(["bash", "-o", "pipefail", "-c",
                        f"{sys.executable} -m embodied_snap.cli claims --ledger {tmp_path / 'claims.csv'} | head -1"],
                       capture_output=True, text=True, cwd=tmp_path, env=env, timeout=60)
    assert r.stderr == "" and r.stdout.count("\n") == 1 and r.returncode == 141, r


def test_claims_filters_name_the_sections_and_statuses_there_are(cwd, capsys):
    """A section the ledger does not hold, or a status no claim can have, is one line (exit 2) naming
    those there are, not "0 paper numbers"; every status a row can have is a filter."""
    from embodied_snap.paper import ledger

    (cwd / "results/tables").mkdir(parents=True)
    with open(cwd / "results/tables/claims.csv", "w", newline="") as f:
        w = csv.DictWriter(f, ledger.COLUMNS)
        w.writeheader()
        for k, (sec, status) in enumerate([("IV-A", ledger.AGREES), ("III-B", ledger.BY_CONSTRUCTION),
                                           ("III-A", ledger.DIFFERS), ("III-B", ledger.NO_PAPER)]):
            w.writerow(dict.fromkeys(ledger.COLUMNS, "") | dict(claim_id=f"c{k}", section=sec, status=status))
    for argv, says in ((["--section", "nosuch"], "--section nosuch: no such section in results/tables/claims.csv "
                        "(sections: III-A, III-B, IV-A)"),
                       (["--section", "III-B", "--section", "V"], "--section V: no such section in "
                        "results/tables/claims.csv (sections: III-A, III-B, IV-A)"),
                       (["--status", "nosuch"], "--status nosuch: no such claim status (statuses: agrees, differs, "
                        "by construction, not measured, no paper value)")):
        rc, err = esnap(capsys, ["claims", *argv])
        assert rc == 2 and err == [f"esnap claims: error: {says}"], (argv, rc, err)
    for status in ledger.STATUSES:
        assert esnap(capsys, ["claims", "--status", status])[0] == 0
    rc = cli.main(["claims", "--section", "III-B", "--status", "by construction"])
    out = capsys.readouterr().out.splitlines()
    assert rc == 0 and len(out) == 2 and out[1].split()[:2] == ["III-B", "c1"], out


def test_a_bug_is_one_line_or_its_traceback(cwd, capsys, monkeypatch):
    """The catch-all: an exception no command expects is one line; ESNAP_DEBUG=1 lets it through."""
    from embodied_snap.paper import ledger

    (cwd / "results/tables").mkdir(parents=True)
    (cwd / "results/tables/claims.csv").write_text(",".join(ledger.COLUMNS) + "\n")

    def broken(path):
        raise RuntimeError("a bug\nover two lines")

    monkeypatch.setattr(ledger, "read", broken)
    rc, err = esnap(capsys, ["claims"])
    assert rc == 1 and err == ["esnap claims: internal error: RuntimeError: a bug over two lines "
                               "(ESNAP_DEBUG=1 shows the traceback)"]
    monkeypatch.setenv("ESNAP_DEBUG", "1")
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main(["claims"])

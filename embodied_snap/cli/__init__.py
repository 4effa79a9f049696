"""`esnap`: the project's command line. Each subcommand is a thin call into the package.

Every bad invocation is one line on stderr: exit status 2 for a usage error (a bad argument, a
missing file, a config that breaks the schema), 1 for a check that failed, 130 on Ctrl-C; a closed
pipe (`esnap claims | head`) ends quietly. Anything else is a bug: one "internal error" line, and
ESNAP_DEBUG=1 shows its traceback.
"""

# The commands live in one module per family (data, lineage, lab, budget), each holding its
# sub-parsers and their functions; what they share is in common.py. Every module imports the
# package's heavy parts (the simulated rig, the lab client, numpy) inside its command functions, so
# that `esnap --help` stays quick.

from __future__ import annotations

import argparse
import os
import sys

from . import budget, data, lab, lineage
from .common import Parser, UsageError, one_line


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("embodied-snap")
    except PackageNotFoundError:  # run from a checkout that was never installed
        return "unknown (not installed)"


def parser() -> argparse.ArgumentParser:
    p = Parser(prog="esnap", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    # in the order `esnap --help` lists them
    data.add_twin(sub)
    data.add_gate(sub)  # validate, seal
    data.add_import(sub)
    lineage.add_audit(sub)
    lineage.add_check_separation(sub)
    lineage.add_prov(sub)
    budget.add_resources(sub)
    lab.add_lab(sub)
    lab.add_deploy(sub)
    lab.add_deploy_index(sub)
    lineage.add_claims(sub)
    lineage.add_crate(sub)
    budget.add_budget(sub)
    lineage.add_report_check(sub)
    return p


def _config_last(argv: list[str]) -> list[str]:
    """`--config K=V ...` moved to the end (before any `--`): it takes every K=V after it, and at
    the end it cannot swallow a positional (`esnap audit --config budget=smoke RESULT`)."""
    head, moved, i = [], [], 0
    while i < len(argv):
        if argv[i] == "--":
            break
        if argv[i] == "--config":
            j = i + 1
            while j < len(argv) and "=" in argv[j] and not argv[j].startswith("-"):
                j += 1
            moved += argv[i:j]
            i = j
        else:
            head.append(argv[i])
            i += 1
    return head + moved + argv[i:]


def main(argv: list[str] | None = None) -> int:
    from ..runconfig import ConfigError

    argv = _config_last(list(sys.argv[1:] if argv is None else argv))
    prog = "esnap"
    try:
        a = parser().parse_args(argv)
        a.argv = ["esnap", *argv]  # the command as given, for a line that says how to ask again
        prog = f"esnap {a.cmd}"
        rc = a.fn(a)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return rc
    except UsageError as e:
        print(f"{e.prog or prog}: error: {e}", file=sys.stderr)
        return 2
    except ConfigError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader has gone (`esnap claims | head`): what it read was all it wanted
        _stdout_to_devnull()
        return 141  # as a shell reports a process that SIGPIPE ended
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 -- a bug: one line here, the traceback on request
        if os.environ.get("ESNAP_DEBUG") == "1":
            raise
        print(f"{prog}: internal error: {type(e).__name__}: {one_line(e)} (ESNAP_DEBUG=1 shows the traceback)",
              file=sys.stderr)
        return 1


def _stdout_to_devnull() -> None:
    """So that the interpreter's last flush of stdout does not fail on the closed pipe too."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # not a real file (a test's capture): nothing to flush there
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)

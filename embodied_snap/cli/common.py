"""What every `esnap` command shares: the one-line usage error, the parser class that raises it,
the checks on path arguments, and the run's config options."""

from __future__ import annotations

import argparse
from pathlib import Path


class UsageError(Exception):
    """A bad argument: one line on stderr, exit status 2. `prog`: the (sub)command it is about."""

    def __init__(self, message: str, prog: str | None = None):
        super().__init__(message)
        self.prog = prog


class Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, not argparse's usage block
        raise UsageError(f"{message} (see: {self.prog} --help)", self.prog)


def given_path(path, what: str) -> Path:
    if not str(path).strip():  # Path("") is "."
        raise UsageError(f"{what}: empty path")
    return Path(path)


def existing_dir(path, what: str) -> Path:
    if not given_path(path, what).is_dir():
        raise UsageError(f"{what} {path}: no such directory")
    return Path(path)


def existing_file(path, what: str) -> Path:
    if not given_path(path, what).is_file():
        raise UsageError(f"{what} {path}: no such file")
    return Path(path)


def made_dir(path, what: str) -> Path:
    """A directory to write into, made now (before any work) if it is not there."""
    try:
        given_path(path, what).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"{what} {path}: cannot make it a directory ({e.strerror or e})") from None
    return Path(path)


def load_config(a, root=".") -> dict:
    """The run's config: config.yaml, --configfile, --config (embodied_snap/runconfig.py)."""
    from .. import runconfig

    return runconfig.load(a.configfile, a.config, root=root)


def config_args(sp, default_help: str = "default: config.yaml") -> None:
    from .. import runconfig

    runconfig.add_arguments(sp, default_help)


def positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n}: expected 1 or more")
    return n


def one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__

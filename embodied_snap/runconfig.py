"""The run's config as Snakemake builds it, for the `esnap` commands that read it.

The workflow's config.yaml, extended by `--configfile FILE` and `--config KEY=VALUE ...`, parsed
and merged by Snakemake's own helpers, then validated against schemas/config.schema.yaml with Snakemake's
`validate`, as the Snakefile does (the schema has no defaults: it requires every key config.yaml
defines, so a config that lacks one is refused, never filled in): a command sees the config a run with the
same arguments would see. Any error is one line (ConfigError), never the whole schema.
Snakemake and yaml are imported inside the functions, so that the CLI's parser can use this module
on the lab PC, where `esnap deploy` has numpy and dynamixel-sdk alone.
"""

from __future__ import annotations

import re
from pathlib import Path

from .policy.architectures import seeds_error
from .schemacheck import violation

SCHEMA = Path(__file__).resolve().parent.parent / "schemas" / "config.schema.yaml"
DEFAULT = "config.yaml"


class ConfigError(ValueError):
    """The config cannot be used: one line naming the file or the key and the rule."""


def add_arguments(parser, default_help: str = f"default: {DEFAULT}") -> None:
    """The two options, as snakemake spells them. --config takes one or more KEY=VALUE (the CLI
    moves them behind any positional, cli._config_last); given twice, both lists count."""
    parser.add_argument("--configfile", metavar="FILE", help=f"the run's config file ({default_help})")
    parser.add_argument("--config", nargs="+", action="extend", metavar="KEY=VALUE", default=[],
                        help="config overrides, as for snakemake (YAML values, e.g. budget=smoke)")


def overrides(entries) -> dict:
    """--config KEY=VALUE ... as Snakemake parses it (snakemake.cli.parse_config)."""
    from snakemake.cli import parse_config

    try:
        return parse_config(list(entries or []))
    except ValueError as e:
        raise ConfigError(f"--config: {e}") from None


def validate(cfg: dict) -> dict:
    """`cfg` checked against the schema as the Snakefile checks it (the schema has no defaults to fill in)."""
    err = violation(cfg, SCHEMA)
    if err:
        raise ConfigError(f"config: {err}")
    err = beyond_schema_error(cfg)
    if err:
        raise ConfigError(err)
    return cfg


def beyond_schema_error(cfg: dict) -> str | None:
    """One line naming a key the schema cannot judge (names_error, pattern_error), as its own
    errors read; None if there is none. The Snakefile checks it after the schema, as `esnap` does."""
    return names_error(cfg) or pattern_error(cfg)


def names_error(cfg: dict) -> str | None:
    """One line naming a key the schema leaves to the table that holds its names: a budget's
    evidence set or category (rawformat.EVIDENCE) or architecture (policy/architectures.py), unknown
    or (architectures) missing; None if all are known (beyond_schema_error)."""
    from .rawformat import groups_error  # pandas: not on the lab PC, where no config is checked

    return groups_error(cfg) or seeds_error(cfg)


def pattern_error(cfg: dict) -> str | None:
    """One line if raw_data.group_id_pattern is not a regular expression (every reader of
    index.csv and the plan match group ids with it); None if it compiles."""
    pattern = cfg["raw_data"]["group_id_pattern"]
    try:
        re.compile(pattern)
    except re.error as e:
        return (f"config: raw_data.group_id_pattern: {pattern!r} is not a regular expression ({e}) "
                "(rule: group ids match a Python regular expression)")
    return None


def _read(path: Path) -> dict:
    from snakemake.common.configfile import load_configfile
    from snakemake.exceptions import WorkflowError

    if not path.is_file():
        raise ConfigError(f"--configfile {path}: no such file")
    try:
        return load_configfile(str(path))
    except (WorkflowError, OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"--configfile {path}: {' '.join(str(e).split())}") from None


def load(configfile=None, entries=(), root=".") -> dict:
    """The config of a run given `--configfile configfile --config entries...` in `root`: as
    Snakemake merges them, the workflow's config.yaml, updated by the file, then by the entries."""
    from snakemake.utils import update_config

    if configfile is not None and not str(configfile).strip():
        raise ConfigError("--configfile: empty path")
    base = Path(root) / DEFAULT
    cfg = _read(base) if base.is_file() or not configfile else {}
    if configfile:
        update_config(cfg, _read(Path(root) / configfile))
    update_config(cfg, overrides(entries))
    return validate(cfg)


def given(a) -> bool:
    """Whether the command line named a config (else audit and check-separation use the last run's)."""
    return a.configfile is not None or bool(a.config)

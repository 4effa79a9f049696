"""A document against its JSON schema, in one line: the config (the Snakefile through Snakemake's
`validate`, esnap through runconfig) and the lab file (capture.lab) are checked the same way."""

from __future__ import annotations

import functools
from pathlib import Path


def error_line(e: Exception) -> str:
    """One line for a jsonschema error or a failed `snakemake.utils.validate` (the Snakefile's): the
    key path and the rule. The rule is the schema's `errorMessage` for the failed keyword where it
    gives one (jsonschema's own message can print a whole value), else jsonschema's message."""
    import jsonschema

    err = e
    while err is not None and not isinstance(err, jsonschema.ValidationError):
        err = err.__cause__ or err.__context__  # snakemake raises its error while handling jsonschema's
    if err is None:
        return " ".join(str(e).split())
    rule = err.schema.get("errorMessage") if isinstance(err.schema, dict) else None
    if isinstance(rule, dict):
        rule = rule.get(err.validator)
    where = ".".join(str(k) for k in err.absolute_path)
    return (f"{where}: " if where else "") + (rule or " ".join(err.message.split()))


@functools.cache
def validator(schema: Path):
    """The validator `snakemake.utils.validate` builds for `schema` (Draft 2020-12; its refs are
    inside the file), read once per process: Snakemake reads the YAML again on every call (0.14 s).
    Our schemas give no defaults (tests/test_one_door.py), so Snakemake's default-filling is moot."""
    import yaml
    from jsonschema import Draft202012Validator

    return Draft202012Validator(yaml.load(Path(schema).read_text(), Loader=yaml.CSafeLoader))


def violation(doc: dict, schema) -> str | None:
    """None when `doc` satisfies `schema` (a path), else its error_line: the first error, as
    Snakemake's `validate` raises it."""
    err = next(validator(Path(schema).resolve()).iter_errors(doc), None)
    return None if err is None else error_line(err)

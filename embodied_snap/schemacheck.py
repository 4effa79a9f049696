"""A document against its JSON schema, through Snakemake's own validator, in one line: the config
(the Snakefile and runconfig) and the lab file (capture.lab) are checked the same way."""

from __future__ import annotations


def error_line(e: Exception) -> str:
    """One line for a failed `snakemake.utils.validate`: the key path and the rule. The rule is the
    schema's `errorMessage` for the failed keyword where it gives one (jsonschema's own message can
    print a whole value), else jsonschema's message."""
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


def violation(doc: dict, schema) -> str | None:
    """None when `doc` satisfies `schema` (a path), else its error_line."""
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import validate

    try:
        validate(doc, str(schema))
    except WorkflowError as e:
        return error_line(e)
    return None

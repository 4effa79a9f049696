"""The paper as a build product: the claims ledger, Table I from the lineage, report captions and
the Workflow Run RO-Crate (docs/report.md)."""

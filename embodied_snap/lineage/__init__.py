"""Lineage: provenance records of every job (`records`), `esnap audit` (`audit`), the evidence-set
allow list (`policy`), the Snakemake job graph (`dag`), the separation proofs (`checks`) and the
PROV-JSON export (`prov`). See docs/lineage.md."""

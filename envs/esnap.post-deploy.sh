#!/usr/bin/env bash
# Snakemake runs this once in the new esnap environment (snakemake --sdm conda), from the workflow
# directory: the embodied_snap package, editable, so jobs import the repository's code (the code
# their rules declare) and the dependencies stay the pins of esnap.yaml.
set -euo pipefail
python -m pip install --no-deps -e .

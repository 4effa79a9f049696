# The README's two commands: `make paper` (install + every figure from raw data) and `make test`.
VENV ?= .venv
PY := $(VENV)/bin/python
# BUDGET=smoke|quick|paper; empty: config.yaml's budget, as a bare snakemake or esnap means
BUDGET ?=
CORES ?= 2
ASK := $(if $(BUDGET),--config budget=$(BUDGET))

.PHONY: paper test install lint format clean cluster-test

# Python 3.11 exactly (pyproject's requires-python; the lock is solved for it): another stops here.
PYTHON ?= python3

$(VENV)/.installed: pyproject.toml requirements.lock
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else \
		f"make: Python 3.11 is needed and $(PYTHON) is {sys.version.split()[0]}: give one, e.g. make PYTHON=python3.11")'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# torch first and pinned: the CPU build, never a multi-GB CUDA one
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -r requirements.lock
	$(PY) -m pip install -q --no-deps -e .
	# the report test opens the HTML report in the system's Chromium (docs/report.md): Debian's package
	command -v chromium >/dev/null || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && \
		apt-get update -q && apt-get install -y -q -o DPkg::Lock::Timeout=300 chromium; } || echo "no chromium: the report test skips"
	touch $@

install: $(VENV)/.installed

# raw_data/ and results/ hold one budget's run: switch to this one first (the other's are kept
# in .budgets/, docs/design.md "Budgets").
paper: install
	$(VENV)/bin/esnap budget $(BUDGET)
	$(VENV)/bin/snakemake --cores $(CORES) all $(ASK)
	$(VENV)/bin/snakemake --report results/report.html $(ASK)

test: install
	$(VENV)/bin/pytest -q

# A one-node SLURM cluster on this machine (root; installs slurm and munge from Debian if missing):
# the smoke DAG through profiles/slurm, compared with a local run (docs/cluster.md).
cluster-test: install
	VENV=$(VENV) bash cluster/cluster-test.sh

lint: install
	$(VENV)/bin/snakemake --lint
	$(VENV)/bin/snakefmt --check Snakefile rules
	$(VENV)/bin/ruff check .

format: install
	$(VENV)/bin/snakefmt Snakefile rules

clean:
	rm -rf results logs benchmarks .snakemake

# The README's two commands: `make paper` (install + every figure from raw data) and `make test`.
VENV ?= .venv
PY := $(VENV)/bin/python
# BUDGET=smoke|quick|paper; empty: config.yaml's budget, as a bare snakemake or esnap means
BUDGET ?=
CORES ?= 2
ASK := $(if $(BUDGET),--config budget=$(BUDGET))

.PHONY: paper test test-fast install lint format clean cluster-test mutation

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

# Two workers (pytest-xdist), a test module per worker at a time, in the order tests/conftest.py
# gives: the session's smoke run starts building at once while the other modules run beside it.
XDIST := -n $(CORES) --dist loadfile --no-loadscope-reorder
test: install
	$(VENV)/bin/pytest -q $(XDIST)

# The edit loop (CONTRIBUTING.md): the unit tests alone, no workflow run (the `slow` marker).
test-fast: install
	$(VENV)/bin/pytest -q $(XDIST) -m "not slow"

# A three-node SLURM cluster on this machine (network namespaces; root; installs slurm and munge from Debian if missing):
# the smoke DAG through profiles/slurm, compared with a local run (docs/cluster.md).
cluster-test: install
	VENV=$(VENV) bash cluster/cluster-test.sh

# Mutation testing (docs/benchmarks.md "Mutation score"; not in .ci/run, not in `make test`): mutmut
# ([tool.mutmut] in pyproject.toml) mutates the functions below, the ones that decide what gets in
# (the gate, the lineage checks) and what moves the arm (the deployment's commands, preflight and
# checks), runs each mutant against the fast unit tests that reach it, one worker, and prints the
# score. MUTANTS=<globs or mutant names> narrows it (e.g. MUTANTS='embodied_snap.deploy.commands.*').
MUTANTS ?= 'embodied_snap.lineage.policy.*' \
	$(foreach f,check_declared check_watched _audit raw_dir_of is_code _in_job _rel _named _flat _watch _stop_watching load_records,'embodied_snap.lineage.records.x_$(f)__mutmut_*') \
	$(foreach f,x_commands x_plan x_check_envelope,'embodied_snap.deploy.commands.$(f)__mutmut_*') \
	$(foreach f,x_preflight x*Bus*_check x*Bus*torque_off x*Bus*_silent_servo x*Bus*_short_reply,'embodied_snap.deploy.client.$(f)__mutmut_*') \
	$(foreach f,_check_motion _check_meta _check_servo _longest,'embodied_snap.validate.x_$(f)__mutmut_*') \
	$(foreach f,_mocap_passes _servo_passes _body_checks _meta_passes _sorted_finite_t _rate_check _strictly_increasing _within,'embodied_snap.rawschema.x_$(f)__mutmut_*')
mutation: install
	rm -rf mutants
	$(VENV)/bin/mutmut run --max-children 1 $(MUTANTS) > /dev/null
	$(VENV)/bin/mutmut results --all true | $(PY) -c "$$MUTATION_SCORE" $(MUTANTS)

# `mutmut results --all true` -> per module: mutants, killed, survived, no tests, timeout, suspicious, not
# checked; the score is over the checked ones, a timeout counted as killed, a mutant no test reaches as survived.
define MUTATION_SCORE
import collections, fnmatch, sys
globs, n = sys.argv[1:], collections.defaultdict(collections.Counter)
for line in sys.stdin:
    name, _, status = line.strip().rpartition(": ")
    if name and any(fnmatch.fnmatchcase(name, g) for g in globs):
        n[name.split(".x")[0]][status] += 1
cols = ("killed", "survived", "no tests", "timeout", "suspicious", "not checked")
print(f"{'module':34} {'mutants':>7} " + " ".join(f"{c:>10}" for c in cols))
tot = collections.Counter()
for mod, c in sorted(n.items()):
    tot.update(c)
    print(f"{mod:34} {sum(c.values()):7} " + " ".join(f"{c[k]:10}" for k in cols))
done = sum(tot.values()) - tot["not checked"]
print(f"{'all':34} {sum(tot.values()):7} " + " ".join(f"{tot[k]:10}" for k in cols))
print(f"mutation score {100 * (tot['killed'] + tot['timeout']) / max(done, 1):.1f} % of {done} mutants checked")
endef
export MUTATION_SCORE

lint: install
	$(VENV)/bin/snakemake --lint
	$(VENV)/bin/snakefmt --check Snakefile rules
	$(VENV)/bin/ruff check .

format: install
	$(VENV)/bin/snakefmt Snakefile rules

clean:
	rm -rf results logs benchmarks .snakemake

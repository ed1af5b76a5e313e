# osmap: set-up, demo, tests, benchmarks (GNU make).
#
#   make demo    create .venv, install osmap, synthesize two sample textures into out/ (timed)
#   make test    create .venv, install osmap, run the test suite
#
# Only Python >= 3.10 with pip (and a C compiler if a dependency has no wheel) is needed:
# everything else comes from PyPI. Override the virtualenv folder with `make VENV=/path ...`.

VENV ?= .venv
PYTHON ?= python3
PY = $(VENV)/bin/python
OSMAP = $(VENV)/bin/osmap
# Touched after a successful install; re-installs when pyproject.toml changes.
STAMP = $(VENV)/.osmap-installed

.DEFAULT_GOAL := help
.PHONY: help venv demo test bench mutants lint clean distclean

help:
	@echo "make demo       set up $(VENV) and synthesize two samples into out/"
	@echo "make test       set up $(VENV) and run the tests"
	@echo "make bench      set up $(VENV) and run the benchmarks (writes BENCHMARKS.md)"
	@echo "make mutants    set up $(VENV) and run mutation testing (slow; outside CI)"
	@echo "make lint       ruff check ."
	@echo "make venv       only create $(VENV) and install osmap (editable, dev tools, dask cluster)"
	@echo "make clean      remove out/ and caches; make distclean also removes $(VENV)"

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet "pip>=21.3"
	$(PY) -m pip install --quiet -e ".[dev,cluster]"
	@touch $@

# `pip install .` ships kernels compiled for any CPU of this kind (buildhook/osmap_build.py); the
# editable install of $(VENV) does not, so demo builds them for this tree (about 60 s on two
# cores; again only when a kernel changed), then times each synthesis (the first one is the
# first run after the install).
TIMED = $(PY) -c "import subprocess, sys, time; t = time.perf_counter(); code = subprocess.call(sys.argv[1:]); print(f'demo: {sys.argv[3]} -> {sys.argv[5]} in {time.perf_counter() - t:.1f} s', file=sys.stderr); sys.exit(code)"

demo: venv
	@mkdir -p out
	@$(PY) -m osmap_cli.kernelwarm portable --if-stale kernels/portable-cache
	@$(TIMED) $(OSMAP) synth samples/cells.png -o out/cells_synth.png --size 256
	@$(TIMED) $(OSMAP) synth samples/brick.png -o out/brick_synth.png --size 256 --preset structured
	@echo "demo outputs: out/cells_synth.png (from samples/cells.png), out/brick_synth.png (from samples/brick.png)"

test: venv
	$(PY) -m pytest

# MiniSom is a benchmark-only dependency (the classic-SOM comparison), not a runtime one.
bench: venv
	$(PY) -m pip install --quiet minisom
	$(PY) bench/run.py

# Mutation testing (docs/testing.md): mutmut is installed here, not as a test dependency. One
# mutmut run per module, with the test files aimed at it (tests/mutation_run.py); MODULES picks
# the modules. Hours on two shared cores: outside CI.
MODULES ?= schedule options organise output provenance batch
mutants: venv
	$(PY) -m pip install --quiet "mutmut==3.8.1"
	for module in $(MODULES); do nice -n 10 $(PY) tests/mutation_run.py $$module || exit 1; done
	$(PY) tests/mutation_report.py $(MODULES)

lint: venv
	$(PY) -m ruff check .

clean:
	rm -rf out build dist mutants .pytest_cache .ruff_cache *.egg-info kernels/portable-cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)

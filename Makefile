# osmap: set-up, demo, tests, benchmarks (GNU make).
#
#   make demo    create .venv, install osmap, synthesize two sample textures into out/
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

demo: venv
	@mkdir -p out
	$(OSMAP) synth samples/cells.png -o out/cells_synth.png --size 256
	$(OSMAP) synth samples/brick.png -o out/brick_synth.png --size 256 --preset structured
	@echo "demo outputs: out/cells_synth.png (from samples/cells.png), out/brick_synth.png (from samples/brick.png)"

test: venv
	$(PY) -m pytest

# MiniSom is a benchmark-only dependency (the classic-SOM comparison), not a runtime one.
bench: venv
	$(PY) -m pip install --quiet minisom
	$(PY) bench/run.py

# Mutation testing (docs/testing.md): mutmut is installed here, not as a test dependency. It
# mutates the modules where bugs are silent and runs the test files aimed at them (the
# [tool.mutmut] table of pyproject.toml); MUTANTS picks which mutants (of engine.py, the schedule).
MUTANTS ?= osmap_cli.output.* osmap_cli.provenance.* osmap_cli.options.* osmap_cli.batch.* \
	osmap_cli.engine.xǁScheduleǁ* osmap_cli.synth.organise.*
mutants: venv
	$(PY) -m pip install --quiet "mutmut==3.8.1"
	nice -n 10 $(VENV)/bin/mutmut run $(foreach p,$(MUTANTS),'$(p)')
	$(PY) tests/mutation_report.py $(foreach p,$(MUTANTS),'$(p)')

lint: venv
	$(PY) -m ruff check .

clean:
	rm -rf out build dist mutants .pytest_cache .ruff_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)

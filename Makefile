# Set-up, build and test. Every target is idempotent and fast when nothing changed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo example test fmu venv docs doc-outputs clean

demo: $(STAMP) fmu
	$(VENV)/bin/cosim run racetrack --out runs/demo

# A second system on the framework: the DC motor FMU (pythonfmu; built once per source, cached
# in examples/dc_motor/build/) under PI speed control.
example: $(STAMP)
	$(PY) examples/dc_motor/build.py
	$(VENV)/bin/cosim run examples/dc_motor/scenario.yaml --out runs/dc_motor

# The linter (ruff, configured in pyproject.toml), then the suite (the docs' site build included; the 15
# slowest tests listed at the end).
test: $(STAMP) fmu
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -n auto --dist loadscope --durations=15

# The plant FMU, built from the package's C sources into ~/.cache/cosim-swimmer/fmu on first use
# (a run builds it too); prints its path. COSIM_FMU=FILE runs a prebuilt one instead.
fmu: $(STAMP)
	@$(PY) -m cosim_plugins.plant.build

venv: $(STAMP)

# The docs as a site in build/site (mkdocs serve: at http://127.0.0.1:8000, rebuilt as pages change).
docs: $(STAMP)
	$(VENV)/bin/mkdocs build --strict

# Every command output the docs show, made again (tools/doc_outputs.py; --quick: the fast ones), and
# the measured tables rendered from the benchmarks' kept JSON in docs/benchmarks/data (tools/bench_tables.py).
doc-outputs: $(STAMP)
	$(PY) tools/doc_outputs.py
	$(PY) tools/bench_tables.py

# torch is pinned to the local CPU wheel first so nothing pulls CUDA packages.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[test,lab,cluster,docs,mutation]'
	touch $@

clean:
	rm -rf build runs cache

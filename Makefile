# Set-up, build and test. Every target is idempotent and fast when nothing changed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
FMU := build/swimmer_plant.fmu
FMU_SOURCES := $(wildcard fmus/swimmer_plant/*.c fmus/swimmer_plant/*.h fmus/swimmer_plant/*.xml)

.PHONY: demo example test fmu venv clean

demo: $(STAMP) $(FMU)
	$(VENV)/bin/cosim run scenarios/racetrack.yaml --out runs/demo

# A second system on the framework: the DC motor FMU (pythonfmu; built once per source, cached
# in examples/dc_motor/build/) under PI speed control.
example: $(STAMP)
	$(PY) examples/dc_motor/build.py
	$(VENV)/bin/cosim run examples/dc_motor/scenario.yaml --out runs/dc_motor

test: $(STAMP) $(FMU)
	$(PY) -m pytest -n auto --dist loadscope

fmu: $(FMU)

venv: $(STAMP)

# torch is pinned to the local CPU wheel first so nothing pulls CUDA packages.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[test,lab,cluster,mutation]'
	touch $@

$(FMU): $(STAMP) $(FMU_SOURCES)
	$(PY) -m cosim_plugins.plant.build --out $@

clean:
	rm -rf build runs cache

# Set-up, build and test. Every target is idempotent and fast when nothing changed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
FMU := build/swimmer_plant.fmu
FMU_SOURCES := $(wildcard fmus/swimmer_plant/*.c fmus/swimmer_plant/*.h fmus/swimmer_plant/*.xml)

.PHONY: demo test fmu venv clean

demo: $(STAMP) $(FMU)
	$(VENV)/bin/cosim run scenarios/racetrack.yaml --out runs/demo

test: $(STAMP) $(FMU)
	$(PY) -m pytest

fmu: $(FMU)

venv: $(STAMP)

# torch is pinned to the local CPU wheel first so nothing pulls CUDA packages.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[test,lab,cluster]'
	touch $@

$(FMU): $(STAMP) $(FMU_SOURCES)
	$(PY) -m cosim_plugins.plant.build --out $@

clean:
	rm -rf build runs cache

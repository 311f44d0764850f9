# inertia_ros: two commands on a fresh machine.
#   make demo   runs the main job (simulator + estimator over DDS) on the default scene
#   make test   creates the venv if needed and runs the whole test suite
# The virtual environment is created from the pinned requirements and reused while they match.

PYTHON ?= python3.11
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
REQS   := requirements.txt requirements-test.txt setup.py package.xml

.PHONY: all venv test test-fast demo bench bags lint clean help
.DEFAULT_GOAL := help

help:
	@echo "make demo    run the live demo on the default scene (creates .venv)"
	@echo "make test    run the test suite (creates .venv)"
	@echo "make bench   speed/accuracy benchmarks -> docs/"
	@echo "make bags    regenerate the sample logs in bags/"
	@echo "make lint    ruff on the whole tree"

venv: $(STAMP)

$(STAMP): $(REQS)
	@command -v $(PYTHON) >/dev/null 2>&1 || { \
	  echo "inertia_ros needs Python 3.11: '$(PYTHON)' was not found (install python3.11 or run make PYTHON=/path/to/python3.11)"; exit 2; }
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || { \
	  echo "inertia_ros needs Python 3.11 (ROS 2 Jazzy wheels): '$(PYTHON)' is $$($(PYTHON) -c 'import platform; print(platform.python_version())'); run make PYTHON=/path/to/python3.11"; exit 2; }
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-test.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	@touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

test-fast: $(STAMP)
	$(PY) -m pytest -q -m "not slow"

demo: $(STAMP)
	$(PY) -m inertia_ros demo

bench: $(STAMP)
	$(PY) -m inertia_ros bench

bags: $(STAMP)
	$(PY) scripts/make_bags.py

lint: $(STAMP)
	$(PY) -m ruff check .

clean:
	rm -rf build install log .pytest_cache .ruff_cache

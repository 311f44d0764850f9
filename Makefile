# inertia_ros: two commands on a fresh machine.
#   make demo   runs the main job (simulator + estimator over DDS) on the default scene
#   make test   creates the venv if needed and runs the whole test suite
# The virtual environment is created from the pinned requirements and reused while they match.

PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3 2>/dev/null || echo python3.11)
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
	$(if $(shell command -v '$(PYTHON)' 2>/dev/null),,$(error python '$(PYTHON)' not found; install python3.11 or run make PYTHON=/path/to/python3.11))
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null || { \
	  echo "inertia_ros needs Python 3.11 (the ROS 2 Jazzy wheels are built for it): '$(PYTHON)' is $$($(PYTHON) --version 2>&1 | head -n1 || echo missing); install python3.11 or run make PYTHON=/path/to/python3.11" >&2; exit 2; }
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

# The Pinocchio peer baseline is an optional extra: the bench skips it with a note if the
# install fails.
bench: $(STAMP)
	-$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-bench.txt
	$(PY) -m inertia_ros bench --out docs

bags: $(STAMP)
	$(PY) scripts/make_bags.py

lint: $(STAMP)
	$(PY) -m ruff check .

clean:
	rm -rf build install log .pytest_cache .ruff_cache

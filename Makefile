# Two commands for a fresh machine with only python3: `make run` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: run test lint install bench snapshots docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

## Start the station TUI on simulated devices and a local SQLite database.
run: install
	$(VENV)/bin/station

lint: install
	$(VENV)/bin/ruff check .

## Install, lint and run the default test suite (no slow tests; see `make bench`; the documentation's strict build
## is one of its tests), one process per core
## (pytest-xdist; at most four: the Pilot and process-pool tests start processes of their own).
test: lint
	$(PY) -m pytest -q -n auto --maxprocesses=4

## Remake the screens' snapshots (tests/station/tui/snapshots) after a deliberate change to a screen; then review the SVGs.
snapshots: install
	STATION_UPDATE_SNAPSHOTS=1 $(PY) -m pytest -q tests/station/tui/test_snapshots.py

## The documentation site (MkDocs, Material theme) into build/site, strict: a broken link, a missing page or a page
## left out of the navigation fails. It builds offline; the test suite builds it too (tests/test_docs.py).
docs: install
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir build/site

## Benchmarks print figures; they never fail on timings.
bench: install
	$(PY) -m bench

clean:
	rm -rf $(VENV) build *.egg-info

# sumo_rss developer commands. `make run` and `make test` work on a fresh machine with only python3.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# The CPU build of torch must come first: an unpinned torch pulls gigabytes of CUDA packages.
TORCH  := torch==2.13.0
PYTEST_WORKERS ?= 2

.PHONY: venv install run test acceptance bench nets clean

venv: $(BIN)/python

$(BIN)/python:
	@$(PYTHON) -m venv $(VENV) || { echo "error: '$(PYTHON) -m venv' failed; on Debian/Ubuntu install it with: apt-get install python3-venv" >&2; exit 1; }

install: $(STAMP)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet $(TORCH)
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	@touch $(STAMP)

WORKERS ?= 2

run: install
	$(BIN)/sumo-rss batch scenarios/default.toml --workers $(WORKERS) --out results/default
	$(BIN)/sumo-rss report results/default

test: install
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS)

acceptance: install  # the long checks: issue 48's EPSILON ego on seeds 0-19 of every scenario family against sumo and sumo_restricted, the closed-loop runs, the real-network invariants on a Monaco-size run
	SUMO_RSS_ACCEPTANCE=1 $(BIN)/python -m pytest -q tests/test_planner_acceptance.py tests/test_planner_closed_loop.py -rxX
	# the real-network invariants on a Monaco-size run, where $$SUMO_RSS_REALNETS (default /work/realnets) has one
	SUMO_RSS_ACCEPTANCE=1 $(BIN)/python -m pytest -q tests/test_real_networks_acceptance.py -rs

bench: install
	$(BIN)/python bench/run_all.py

nets: install
	$(BIN)/sumo-rss nets build

clean:
	rm -rf $(VENV) results build *.egg-info .pytest_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

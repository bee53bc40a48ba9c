# roughslip developer commands. `make demo` and `make test` work on a fresh machine with
# Python >= 3.11 and pip: they create .venv and install what they need.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-dev
PYTEST_ARGS ?=

.PHONY: venv test demo bench lint docs clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# Reinstall when the package metadata changes.
$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e '.[dev]'
	@touch $(STAMP)

venv: $(STAMP)

# The documentation (warnings are errors), then the test suite, whose summary closes the
# output. A run that collects no tests fails (pytest's exit code 5): a suite that checks
# nothing must not pass.
test: $(STAMP)
	@$(MAKE) --no-print-directory docs
	@$(PY) -m pytest $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests (PYTEST_ARGS = $(PYTEST_ARGS))"; fi; \
	exit $$rc

# The documentation site: docs/_build/html/index.html. Offline: math is typeset by a local
# MathJax copy; nothing is loaded from the network.
docs: $(STAMP)
	$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

# The main job on a shipped config, its summary, and its figures (results/demo_*.png: the
# friction and load laws, the maps and the pull curve of one sample).
demo: $(STAMP)
	$(VENV)/bin/roughslip run configs/demo.toml -o results/demo.h5 --overwrite
	$(VENV)/bin/roughslip inspect results/demo.h5
	$(VENV)/bin/roughslip plot results/demo.h5 -o results/demo

lint: $(STAMP)
	$(VENV)/bin/ruff check roughslip tests scripts

bench: $(STAMP)
	$(PY) scripts/bench_operator.py
	$(PY) scripts/bench_squeeze.py
	$(PY) scripts/bench_pull.py
	$(PY) scripts/bench_precision.py
	$(PY) scripts/bench_run.py
	$(PY) scripts/bench_coupled.py
	$(PY) scripts/bench_peers.py

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info docs/_build docs/_generated

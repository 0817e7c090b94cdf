# Two entry points, each doing its own set-up on a fresh machine (Python >= 3.11, pip, make).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

# test processes: one per core (pytest-xdist's "auto"); TEST_WORKERS=0 runs the suite in this one process
TEST_WORKERS ?= auto
# each test file runs whole in one process (its module fixtures, an experiment run, made once)
PYTEST := MPLBACKEND=Agg $(BIN)/python -m pytest -p no:cacheprovider --hypothesis-profile=ci \
          -n $(TEST_WORKERS) --dist loadfile

.PHONY: report test test-fast install clean mutation

$(BIN)/python:
	@echo "creating a virtual environment in $(VENV) (first run only)..."
	$(PYTHON) -m venv $(VENV)
	@echo "updating pip in $(VENV)..."
	$(BIN)/python -m pip install --quiet --upgrade pip

# Stamps re-run the install whenever pyproject.toml changes.
$(VENV)/.runtime-installed: pyproject.toml | $(BIN)/python
	@echo "installing gpfverify and its dependencies (numpy, scipy, sympy, casadi, cvxpy, matplotlib, and numba"
	@echo "for the compiled moment kernel) into $(VENV): about a minute on a fresh machine; pip lists each package..."
	$(BIN)/python -m pip install --progress-bar off -e '.[fast]'
	@echo "installed."
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	@echo "installing gpfverify with its test extras into $(VENV): about a minute on a fresh machine..."
	$(BIN)/python -m pip install --progress-bar off -e '.[test]'
	touch $@ $(VENV)/.runtime-installed

install: $(VENV)/.runtime-installed

report: $(VENV)/.runtime-installed
	@echo "building the quick report into reports/quick (several minutes on two cores; one line per step)..."
	$(BIN)/gpfverify report

test: $(VENV)/.test-installed
	$(BIN)/ruff check gpfverify benchmarks
	$(BIN)/mypy
	$(BIN)/lint-imports
	$(PYTEST)

# the inner loop: every test but those marked slow (subprocesses, experiment runs, the browser)
test-fast: $(VENV)/.test-installed
	$(BIN)/ruff check gpfverify benchmarks
	$(BIN)/lint-imports
	$(PYTEST) -m "not slow"

# the sampled mutation report in reports/mutation (hours on two cores; resumes where it stopped)
mutation: $(VENV)/.test-installed
	MPLBACKEND=Agg $(BIN)/python -m tests.mutation.sampled $(ARGS)

clean:
	rm -rf $(VENV) reports/quick

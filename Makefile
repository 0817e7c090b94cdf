# Two entry points, each doing its own set-up on a fresh machine (Python >= 3.11, pip, make).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: report test install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Stamps re-run the install whenever pyproject.toml changes.
$(VENV)/.runtime-installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@ $(VENV)/.runtime-installed

install: $(VENV)/.runtime-installed

report: $(VENV)/.runtime-installed
	$(BIN)/gpfverify report

test: $(VENV)/.test-installed
	MPLBACKEND=Agg $(BIN)/python -m pytest -p no:cacheprovider --hypothesis-profile=ci

clean:
	rm -rf $(VENV) reports/quick

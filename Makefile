# Set-up and the two commands of the README. Each target creates .venv if missing and
# installs the project into it (editable, with the test extra); the install is skipped
# while pyproject.toml is unchanged.
PYTHON ?= python3.11
VENV ?= .venv
PY := $(VENV)/bin/python
INSTALLED := $(VENV)/.installed

.PHONY: demo test install bench lint clean

install: $(INSTALLED)

$(PY):
	$(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)

$(INSTALLED): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(INSTALLED)

demo: $(INSTALLED)
	$(PY) -m experiments.webcam_clipart

# Lint first: a ruff finding fails the target before pytest runs.
test: $(INSTALLED)
	$(VENV)/bin/ruff check rp_jax experiments tests notebooks
	$(PY) -m pytest -q -p no:cacheprovider

# Rules in pyproject.toml ([tool.ruff.lint]); ruff reads the notebooks' code cells too.
lint: $(INSTALLED)
	$(VENV)/bin/ruff check rp_jax experiments tests notebooks

bench: $(INSTALLED)
	$(PY) -m pip install --quiet -e ".[test,bench]"
	$(PY) -m experiments.benchmark

clean:
	rm -rf $(VENV) runs .pytest_cache

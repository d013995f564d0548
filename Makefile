# Set-up and the two commands of the README. Each target creates .venv if missing and
# installs the project into it (editable, with the test extra); the install is skipped
# while pyproject.toml is unchanged.
# The install goes through uv (itself installed from PyPI into .venv), which resolves the
# same versions as pip (`pip freeze` of both environments: the same 114 packages and
# versions, 2026-12-02) in about a quarter of the time; pip is the fallback wherever uv
# cannot be installed or fails. Unlike pip, uv reads no pip.conf: it asks PyPI itself.
PYTHON ?= python3.11
VENV ?= .venv
PY := $(VENV)/bin/python
INSTALLED := $(VENV)/.installed
# apache-beam pins protobuf and pyarrow below what the rest resolves to (6.33 / 25 against
# 7.x / 26), so the Beam build is tested in an environment of its own, layered on .venv: it
# reads .venv's packages (a .pth file) and holds only apache-beam and the versions it pins,
# which come first on its path (the extra beam of pyproject.toml): about a minute to install
# (32 s of CPU) instead of two to four (91 s) for a second copy of everything.
BEAM_VENV ?= .venv-beam
BEAM_PY := $(BEAM_VENV)/bin/python
BEAM_INSTALLED := $(BEAM_VENV)/.installed

.PHONY: demo test test-beam install bench lint clean

install: $(INSTALLED)

$(PY):
	$(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)

$(INSTALLED): pyproject.toml | $(PY)
	( $(PY) -m pip install --quiet uv && \
	  $(PY) -m uv pip install --quiet --python $(PY) --upgrade-package pip pip -e ".[test]" ) || \
	( echo "uv failed: installing with pip" && $(PY) -m pip install --quiet --upgrade pip && \
	  $(PY) -m pip install --quiet -e ".[test]" )
	touch $(INSTALLED)

# From nothing on 2 shared cores (2026-12-02, CPU seconds; README "Two commands" has the
# wall times and loads): install 23 (uv; pip 83-91), render 155-193, label + write 411
# (508 before the matching and SIFT speed-ups, identical records), train 3 epochs ~330.
# Training alone is about 2.5-3 minutes on a quiet machine: the 4-minute target of issue 16
# needs less computed, not faster code.
demo: $(INSTALLED)
	$(PY) -m experiments.webcam_clipart

# Lint first: a ruff finding fails the target before pytest runs. pytest-xdist runs the test
# files on PYTEST_WORKERS processes, each file whole on one worker (--dist loadfile: a
# module's fixtures are built once). Run serially, one core sat idle through most of the
# suite (JAX compiles, OpenCV and Python are mostly one thread): 15-17 min on 2 cores
# against 11 min 54 s to 13 min 48 s in two workers (three clean clones, 2026-12-02; README
# "Two commands").
# The suite writes Python's bytecode (__pycache__ beside each module, in .venv and in the
# checkout, ignored by git) even where PYTHONDONTWRITEBYTECODE is set, as some machines here
# set it: its xdist workers, notebook kernels and the commands it starts would otherwise each
# compile JAX, TensorFlow and the project from source again (importing the training stack:
# 4.9 s of CPU from source, 2.5-2.8 s from bytecode, 2-core AMD EPYC). Only what is imported is
# compiled, once; compiling every installed package at install (uv's --compile-bytecode)
# made the install take 21 s of CPU instead of 2.
# TEST_CACHE keeps what one run computes for the next: JAX's compiled programs, one folder
# per CPU kind (docs/testing.md has what it saves, cold and warm). `make clean` empties it;
# `make test TEST_CACHE=off` runs without it.
PYTEST_WORKERS ?= 2
TEST_CACHE ?= .cache/tests
test: $(INSTALLED)
	$(VENV)/bin/ruff check rp_jax experiments tests notebooks
	PYTHONDONTWRITEBYTECODE= \
	RP_JAX_TEST_CACHE=$(if $(filter off,$(TEST_CACHE)),off,$(abspath $(TEST_CACHE))) \
		$(PY) -m pytest -q -p no:cacheprovider -n $(PYTEST_WORKERS) --dist loadfile

# Rules in pyproject.toml ([tool.ruff.lint]); ruff reads the notebooks' code cells too.
lint: $(INSTALLED)
	$(VENV)/bin/ruff check rp_jax experiments tests notebooks

# The TFDS builders under Apache Beam's DirectRunner (2 processes), in .venv-beam; .ci/run
# calls it after `make test`.
$(BEAM_PY):
	$(PYTHON) -m venv $(BEAM_VENV) || python3 -m venv $(BEAM_VENV)

# The setuptools that `venv` puts in every new environment (65.5 with Python 3.11) would come
# first on .venv-beam's path and hide .venv's (the test extra's setuptools>=77): with the
# bench extra in .venv, `pip check` failed on torch's setuptools>=77.0.3. Beam needs none of
# its own (pip builds packages in isolated environments), so it is removed and .venv's seen.
$(BEAM_INSTALLED): pyproject.toml $(INSTALLED) | $(BEAM_PY)
	echo "import site; site.addsitedir('$$($(PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')')" \
		> "$$($(BEAM_PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/_rp_jax_main_venv.pth"
	$(BEAM_PY) -m pip install --quiet $$($(BEAM_PY) -c 'import tomllib; \
		print(*tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["beam"])')
	$(BEAM_PY) -m pip uninstall --quiet --yes setuptools
	$(BEAM_PY) -m pip check
	touch $(BEAM_INSTALLED)

test-beam: $(BEAM_INSTALLED)
	RP_JAX_REQUIRE_BEAM=1 $(BEAM_PY) -m pytest -q -p no:cacheprovider tests/datasets/test_beam.py

bench: $(INSTALLED)
	$(PY) -m pip install --quiet -e ".[test,bench]"
	$(PY) -m experiments.benchmark

clean:
	rm -rf $(VENV) $(BEAM_VENV) runs .pytest_cache .cache
	find rp_jax experiments tests notebooks -name __pycache__ -type d -prune -exec rm -rf {} +

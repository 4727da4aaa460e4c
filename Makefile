# Two entry points: `make demo` (set up + main demo) and `make test` (set up + lint + tests).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: install demo test bench-track bench-servo

$(STAMP): pyproject.toml tests/plugins/pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# CPU torch first (a local wheel here); the package pins the same version, so nothing else is pulled
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e ".[test]"
	# the outside methods the plugin tests drive (a tracker, a law, a policy registered by entry point)
	$(PY) -m pip install --quiet --no-deps -e tests/plugins
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/hvs-sim demo --out out/demo

test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(PY) -m pytest tests

# lbscene: two commands on a fresh machine — `make demo` and `make test`.
# Each target creates/updates the virtual environment first; a second run skips the install.
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.lbscene-installed
# Headless GL through Mesa's EGL (llvmpipe) on machines without a GPU.
export PYOPENGL_PLATFORM ?= egl

.PHONY: venv demo test test-all bench schemas check-wheel docs clean

$(STAMP): pyproject.toml constraints.txt scripts/install-system-deps.sh
	bash scripts/install-system-deps.sh
	@command -v $(PYTHON) >/dev/null || { echo "need $(PYTHON)"; exit 2; }
	[ -x $(BIN)/python ] || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade "pip>=24" "setuptools>=77" wheel
	# constraints.txt pins numpy<2 (bpy 5.0); every install goes through it.
	$(BIN)/python -m pip install -q -c constraints.txt -e ".[bake,dev]"
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	bash scripts/demo.sh

# the suite runs on every core (pytest-xdist; at most 8 workers, or TEST_WORKERS), tests handed out
# one by one as workers free up; `TEST_WORKERS=0 make test` runs it in one process
TEST_WORKERS ?= auto
PYTEST_PARALLEL := $(if $(filter 0,$(TEST_WORKERS)),,-n $(TEST_WORKERS) --maxprocesses 8 --dist worksteal)

test: $(STAMP)
	bash scripts/install-test-deps.sh
	$(BIN)/pytest -q $(PYTEST_PARALLEL)

test-all: $(STAMP)
	bash scripts/install-test-deps.sh
	$(BIN)/pytest -q -m "" $(PYTEST_PARALLEL)

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

schemas: $(STAMP)
	$(BIN)/python -m lbscene.schemas.export

# the documentation site: reference pages generated from the code, then MkDocs with warnings as errors
DOCS_STAMP := $(VENV)/.lbscene-docs-installed
$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install -q -c constraints.txt -e ".[docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(BIN)/python scripts/gen_docs.py
	$(BIN)/mkdocs build --strict

# sdist -> wheel -> fresh venv (not editable, no bpy) -> validate, build and render a shipped booth
check-wheel: $(STAMP)
	PYTHON=$(BIN)/python PYTHON_BASE=$(PYTHON) bash scripts/check_wheel.sh

clean:
	rm -rf build .pytest_cache

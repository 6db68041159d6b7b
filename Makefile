# critfric: `make demo` solves the shipped paper cases, `make test` runs the test suite, `make docs`
# builds the manual (docs/_build/html).
# Each creates the virtual environment (.venv) and the system libraries gmsh needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEMO   := demo
# pip compiles every module it installs (~20 s of CPU, pandas and dask included); where Python
# may write its bytecode caches, each module is compiled on its first import instead
PIP    := -m pip install -q --disable-pip-version-check $(if $(PYTHONDONTWRITEBYTECODE),,--no-compile)
# both installs' suites: every core a worker, the long tests handed out as workers free up
PYTEST := -m pytest -q -n auto --dist worksteal

.PHONY: all venv demo test test-nofast validate docs fuzz shell clean

all: test

$(STAMP): pyproject.toml
	@bash scripts/system-deps.sh
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null || { \
	  echo "critfric set-up: Python 3.11 or newer is needed as '$(PYTHON)'; install it or run" \
	       "make PYTHON=/path/to/python3.11" >&2; exit 1; }
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV) 2>/dev/null || { rm -rf $(VENV); \
	  echo "critfric set-up: '$(PYTHON) -m venv' does not work here; install the venv module" \
	       "(Debian/Ubuntu: sudo apt-get install python3-venv) and run make again" >&2; exit 1; }
	$(BIN)/python $(PIP) -e '.[test,fast]' \
	  || $(BIN)/python $(PIP) -e '.[test]'
	@touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	@mkdir -p $(DEMO)
	@for f in cases/*.toml; do \
	  name=$$(basename $$f .toml); \
	  echo "solving $$name ..." >&2; \
	  $(BIN)/critfric solve $$f --output $(DEMO)/$$name.h5 --force --json > /dev/null || exit $$?; \
	done
	@$(BIN)/critfric table $(DEMO)/*.h5

test: $(STAMP)
	$(BIN)/python $(PYTEST)

# the same suite on a SciPy-only install (no MKL): what a plain `pip install critfric` gets
NOFAST := .venv-nofast
$(NOFAST)/.installed: pyproject.toml
	@bash scripts/system-deps.sh
	@test -x $(NOFAST)/bin/python || $(PYTHON) -m venv $(NOFAST)
	$(NOFAST)/bin/python $(PIP) -e '.[test]'
	@touch $@

# (the tests marked `once` run in `make test` only: what the sparse solver does not decide, such as
# case files, meshing, bad and hostile inputs and outputs, figures, worker processes and signals,
# the README's commands, the manual and the architecture)
test-nofast: $(NOFAST)/.installed
	$(NOFAST)/bin/python -c 'import importlib.util as u; assert u.find_spec("pypardiso") is None'
	$(NOFAST)/bin/python $(PYTEST) -m "not once"

# the long validation study (minutes; not part of `make test`): h -> 0 limits of graded sweeps
# (unit square, inclined body, mixed contact states; P1, P2, Q1, Q2; five sizes) against
# references and closed forms, written into docs/validation.md; exit 1 if an error bar misses
validate: $(STAMP)
	$(BIN)/python scripts/validate.py --docs docs/validation.md $(if $(JOBS),--jobs $(JOBS))

# the manual (Sphinx: MyST pages, the gallery's scripts run, autodoc, the references generated
# from the schema and the CLI) into docs/_build/html, offline; any warning fails the build
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): pyproject.toml $(STAMP)
	$(BIN)/python $(PIP) -e '.[docs]'
	@touch $@

docs: $(DOCS_STAMP)
	$(BIN)/python -m sphinx -W --keep-going -q -b html -d docs/_build/doctrees docs docs/_build/html
	@echo "the manual: docs/_build/html/index.html" >&2

# a shell with the virtual environment active (critfric on PATH); `exit` leaves it
shell: $(STAMP)
	@echo "critfric is on PATH in this shell; 'exit' leaves it" >&2
	@. $(BIN)/activate && exec $${SHELL:-/bin/sh} -i

# property-based fuzzing of the case loader and the CLI: the test suite's examples, x SCALE
fuzz: $(STAMP)
	CRITFRIC_FUZZ_SCALE=$(or $(SCALE),30) $(BIN)/python -m pytest -q tests/cli/test_fuzz.py tests/cli/test_hostile.py -k 'fuzz or token or msh_headers'

clean:
	rm -rf $(VENV) $(NOFAST) $(DEMO) .pytest_cache .hypothesis docs/_build docs/_generated \
	  docs/auto_examples docs/sg_execution_times.rst

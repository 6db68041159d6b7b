# critfric: `make demo` solves the shipped paper cases, `make test` runs the test suite.
# Both create the virtual environment (.venv) and the system libraries gmsh needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEMO   := demo

.PHONY: all venv demo test clean

all: test

$(STAMP): pyproject.toml
	@bash scripts/system-deps.sh
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --disable-pip-version-check -e '.[test]'
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
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) $(DEMO) .pytest_cache .hypothesis

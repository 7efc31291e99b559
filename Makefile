# hingelab — the two commands: `make demo` (set up + main job) and `make test` (set up + tests).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo

.PHONY: demo test test-all lint bench clean crosscheck peers lock

# The versions are pinned (constraints.txt): a fresh machine computes with the libraries the
# records were made with (the mesher's and CAD kernel's versions move nodes, so numbers).
$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -c constraints.txt -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/hingelab cycle --out $(OUT)

# pytest exits 5 when it collected no test: that must fail, not pass silently.
# Two pytest workers (pytest-xdist): the suite is one core's work, the machine has two.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2; rc=$$?; if [ $$rc -eq 5 ]; then echo "no tests ran" >&2; exit 1; fi; exit $$rc

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m "slow or not slow"

lint: $(STAMP)
	$(BIN)/ruff check cad mesh fe model rsm studies validation tests benchmarks
	$(BIN)/ruff format --check cad mesh fe model rsm studies validation tests benchmarks
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b; done

# The peers some slow tests check against: CalculiX (ccx) and headless chromium (Debian packages,
# needs root). Tests never install anything; without these they skip and name this target.
peers:
	@if command -v ccx >/dev/null && command -v chromium >/dev/null; then echo "ccx and chromium present"; \
	else DEBIAN_FRONTEND=noninteractive apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y calculix-ccx chromium; fi

# Our loops against CalculiX on the same mesh (docs/calculix_crosscheck.md).
crosscheck: $(STAMP) peers
	$(BIN)/python -m pytest -q -m "slow or not slow" tests/fe/interop/test_inp.py tests/fe/interop/test_ccx_crosscheck.py

# Resolve pyproject.toml's ranges anew into constraints.txt, in a scratch venv (an upgrade:
# run `make test-all` and the benchmarks after it, and record that the numbers moved).
LOCK_VENV := .venv-lock
lock:
	rm -rf $(LOCK_VENV) && $(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/pip install --quiet --upgrade pip
	$(LOCK_VENV)/bin/pip install --quiet -e '.[dev]'
	{ sed -n '/^#/p' constraints.txt; $(LOCK_VENV)/bin/pip freeze --exclude-editable; } > constraints.txt.new
	mv constraints.txt.new constraints.txt && rm -rf $(LOCK_VENV)

clean:
	rm -rf $(VENV) out .pytest_cache

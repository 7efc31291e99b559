# hingelab — the two commands: `make demo` (set up + main job) and `make test` (set up + tests).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo

.PHONY: demo test test-all lint bench clean crosscheck peers

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
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

clean:
	rm -rf $(VENV) out .pytest_cache
